"""One flight: the executor (its state and the order of its phases) and its parts, each acting
on it through `state.RunningFlight`: boarding, arrival at the starts and goals, pausing, fault
routing, securing, the flight record with its summary, and the live snapshot."""
