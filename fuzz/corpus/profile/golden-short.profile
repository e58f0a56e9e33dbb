# A short profile for the golden transcripts and unit tests: 20 degC, a 5 degC excursion.
setpoint 20 C
hold 10 min
ramp to 25 C at 1 C/min
hold 5 min
ramp to 20 C at 1 C/min
hold 5 min
