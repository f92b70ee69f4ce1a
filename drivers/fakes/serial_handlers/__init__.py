"""pyserial URL handlers for simulated serial devices (`simprojector://...`)."""
