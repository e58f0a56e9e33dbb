# A ramp faster than the golden configuration's 3 degC/min.
setpoint 20 C
ramp to 30 C at 5 C/min
