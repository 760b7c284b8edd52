"""Keeping a flying fleet safe: the separation margin, vehicle health and the pre-flight gate,
fault detection, the fault policy, the planned landing and a faulty vehicle's descent check."""
