# Qualification of a tactical FOG over its operating range, -40 to +70 degC, nominally
# 8 h 20 min (settles at their minimum). It gives the drift fit what the paper's runs do not:
# three rates (0.5, 1, 2 degC/min) in both directions, so the coil gradient is not one
# constant times the rate; holds right after ramps, where the rate stops but the gradient
# decays with the coil's own time constant; a rate reversal without a hold; the extremes.
# That separation needs a real coil, whose heat reaches the centre by more than one path: on
# the simulator's two-node coil the gradient is exactly -core_tau times the rate, on any
# profile (docs/simulation.md), so there the two paper terms stay collinear.
# Needs a chamber that does -40..+70 degC at 2 degC/min (check_limits refuses it otherwise).

setpoint 20 C
settle within 0.2 C for 5 min           # the air first: a coil settle is meaningless while
                                        # the chamber is still pulling down
# Then the coil, as in exp1.profile (band for self-heating, slope for stability).
settle within 1 C on coil slope 0.02 C/min for 10 min timeout 3 h
hold 10 min                             # random-term reference at 20 degC, as in the paper

# Around room temperature, the paper's range, at three rates.
ramp to 35 C at 0.5 C/min               # slow heating: small gradient for its rate
hold 20 min                             # rate stops, gradient decays: separates the terms
ramp to 5 C at 2 C/min                  # fast cooling: large gradient, sign reversed
hold 20 min
ramp to 20 C at 1 C/min                 # the paper's rate, for comparison with its runs
hold 20 min

# The cold end.
ramp to -40 C at 1 C/min                # 60 min: long enough to reach the steady ramp gradient
hold 30 min                             # gradient decay at the cold end
settle within 1 C on coil slope 0.02 C/min for 10 min timeout 3 h
                                        # leave only from a uniform coil: the next ramp then
                                        # starts from zero gradient

# The whole range in one fast sweep.
ramp to 70 C at 2 C/min                 # 55 min at the fastest rate: the largest gradients
hold 30 min                             # gradient decay at the hot end
settle within 1 C on coil slope 0.02 C/min for 10 min timeout 3 h

# A reversal with no hold between: the rate jumps from -2 to +0.5 degC/min while the
# gradient lags behind it, the clearest separation of rate from gradient in the run.
ramp to 50 C at 2 C/min
ramp to 60 C at 0.5 C/min
hold 20 min

# Home slowly, then a final reference: its bias against the first hold's shows hysteresis.
ramp to 20 C at 0.5 C/min               # 80 min slow cooling
hold 30 min
