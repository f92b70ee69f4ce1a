"""Protocol fakes: stand-ins for the transports (USB HID device, VideoCapture, serial port,
PJLink server) that speak the devices' real protocols, so the real drivers run in tests. Faults are
injected one way (faults.FaultPlan)."""
