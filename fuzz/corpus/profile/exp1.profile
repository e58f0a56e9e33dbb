# Experiment 1 of Wang Chao et al. 2015 (METHOD.md): from 20 degC, 10 degC down and 20 degC
# up at 1 degC/min with 20 min holds. The paper fits its drift model on this run.
setpoint 20 C
# The paper starts "with the chamber at 20 degC and stable"; what must be stable is the coil,
# because the first 10 min hold is the reference for the random term. The slope limit is
# what proves it: 0.02 degC/min times beta1 (-2.733 deg/h per degC/min) is 0.05 deg/h, a third
# of the paper's sigma_a. The band is 1 degC wide because a powered gyro's coil sits above
# the air by its own heating. A coil in its housing can take hours: timeout 3 h.
settle within 1 C on coil slope 0.02 C/min for 10 min timeout 3 h
hold 10 min                 # random-term reference (AR(2) fit)
ramp to 10 C at 1 C/min
hold 20 min
ramp to 30 C at 1 C/min
hold 20 min
ramp to 20 C at 1 C/min
