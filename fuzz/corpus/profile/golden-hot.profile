# Outside the golden configuration's chamber limits (max 60 degC): refused before anything moves.
setpoint 20 C
ramp to 90 C at 1 C/min
hold 10 min
