"""Replanning in flight: new goals, dropped vehicles, a faulty vehicle flown around."""
