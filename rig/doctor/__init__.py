"""`slrig doctor` and `slrig devices`: what is attached to this machine, whether a config fits
it, and the measured display latency of each projector."""
