# Not a profile: the parser names the line and column.
setpoint 20 F
