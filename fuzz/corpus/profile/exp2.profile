# Experiment 2 of Wang Chao et al. 2015 (METHOD.md): the mirror of experiment 1 with half the
# excursion (up 5, down 10, back to 20 degC) at 1 degC/min; a validation run for the model
# fitted on experiment 1.
setpoint 20 C
# Coil stable at 20 degC before the run; see exp1.profile for the choice of band and slope.
settle within 1 C on coil slope 0.02 C/min for 10 min timeout 3 h
hold 10 min                 # random-term reference (AR(2) fit)
ramp to 25 C at 1 C/min
hold 20 min
ramp to 15 C at 1 C/min
hold 20 min
ramp to 20 C at 1 C/min
