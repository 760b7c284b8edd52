"""The SCP core: the separation-free first QP, QP assembly, separation and one-sided rows, the
QP backends and the sequential convex programming loop."""
