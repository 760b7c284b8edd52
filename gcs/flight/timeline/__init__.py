"""The flight's time: the shared setpoint stream that ticks for the whole fleet
(`stream`, real-time scheduling in `realtime`), the flight clock on its ticks with its pauses
(`clock`), and the plans flown in flight time with the motions off them (`flown`).

Below the replans, the safety checks and the run that use them; above the links the stream
sends on.
"""
