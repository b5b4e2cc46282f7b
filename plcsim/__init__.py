"""The simulated PLC and the demo."""
