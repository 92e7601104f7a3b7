"""Simulating the arm: drone physics (drone), flight scenarios (scenarios), the MPU-6050
sensor and register models (imu_model, mpu6050_sim), the AX-12A bus (ax12_sim), the whole
firmware on a simulated board (board), the board behind a serial port (sitl), the closed loop
and its tables (closed_loop, report; `simulate` and `Settings` are importable from here) and the
workspace figure (workspace)."""
from .closed_loop import Run, Settings, ee_error, scenario_flight, servo_lag_of, simulate

__all__ = ["Run", "Settings", "ee_error", "scenario_flight", "servo_lag_of", "simulate"]
