# A settle that the tests meet (coil at the setpoint) or let time out.
setpoint 20 C
settle within 0.5 C on coil for 1 min timeout 5 min
hold 2 min
