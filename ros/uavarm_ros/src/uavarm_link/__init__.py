"""Talking to a board: LLCP framing (llcp), the message codec from the one message table
(messages), the serial client the CLI and calibration use (client; its names are importable
from here), and the ROS 1 node (ros_node)."""
from .client import (ArmLink, CommandRefused, HeartbeatAge, LinkError, LinkGarbled, LinkLate, LinkSilent,
                     PortNotFound)

__all__ = ["ArmLink", "CommandRefused", "HeartbeatAge", "LinkError", "LinkGarbled", "LinkLate", "LinkSilent",
           "PortNotFound"]
