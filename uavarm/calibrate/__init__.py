"""Calibrating a real arm: the guided procedures over the link (guide; the servos'
zeros and directions with their verification move: servo_zero; `imu`, `mounting`, `servos`
and the CLI's `command` are importable from here), the least-squares fits and
stillness checks (fit), and writing results into the model file with its comments kept
(model_edit); and new servos' ids and baud through a Dynamixel adapter (servo_setup, over the
Protocol 1.0 of dxl)."""
from .guide import command, imu, mounting
from .servo_zero import servos

__all__ = ["command", "imu", "mounting", "servos"]
