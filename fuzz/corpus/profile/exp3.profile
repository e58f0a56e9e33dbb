# Experiment 3 of Wang Chao et al. 2015 (METHOD.md): a wider excursion (5 to 35 degC) at the
# slower 0.5 degC/min, back at 1 degC/min; a validation run at a rate the fit has not seen.
setpoint 20 C
# Coil stable at 20 degC before the run; see exp1.profile for the choice of band and slope.
settle within 1 C on coil slope 0.02 C/min for 10 min timeout 3 h
hold 10 min                 # random-term reference (AR(2) fit)
ramp to 5 C at 0.5 C/min
hold 20 min
ramp to 35 C at 0.5 C/min
hold 20 min
ramp to 20 C at 1 C/min
