"""The 1 kHz inner loop: robot state, task maps, collision distances, operational-space control."""

from amex.control.osc import PD, Command, OperationalSpaceController, OSCGains

__all__ = ["PD", "Command", "OSCGains", "OperationalSpaceController"]
