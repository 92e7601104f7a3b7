"""Calibrating a real arm: the guided procedures over the link (guide; `imu`, `mounting`,
`servos` and the CLI's `command` are importable from here), the least-squares fits and
stillness checks (fit), and writing results into the model file with its comments kept
(model_edit)."""
from .guide import command, imu, mounting, servos

__all__ = ["command", "imu", "mounting", "servos"]
