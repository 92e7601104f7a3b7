"""What `make mutate` mutates, and which behavioural tests judge each part.

A target is one row of the score table: a source file, the spans of it that are mutated
(named functions, or a marked span of a template), whether generated/ must be regenerated
from the mutated file (templates and the generator's model modules: so a mutant reaches
generated/ the way a bug would, and the freshness test is not what kills it), and the
tests run against each mutant (fastest first; pytest stops at the first failure).
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Target:
    name: str
    path: str
    spans: tuple          # ("c", function) | ("py", function) | ("mark", first line regex, last line regex)
    tests: tuple          # pytest arguments
    regenerate: bool = False


SAFETY_LAYERS = "tests/test_safety_layers.py"

TARGETS = (
    Target("kin_check_joints (template)", "templates/kinematics.c.j2",
           (("mark", r"^static inline bool within_limits", r"^    return KIN_OK;"),),
           (SAFETY_LAYERS, "tests/test_collision.py"), regenerate=True),
    Target("kin_check_joints (model: limits, body, legs)", "model/collision.py",
           (("py", "body_clear"), ("py", "leg_planes"), ("py", "near_leg"), ("py", "_near_leg_angle"),
            ("py", "legs_clear")),
           (SAFETY_LAYERS, "tests/test_collision.py", "tests/test_motion_kinematics.py"), regenerate=True),
    Target("kin_check_joints (model: joint limits)", "model/kinematics.py", (("py", "joint_limits_ok"),),
           (SAFETY_LAYERS, "tests/test_collision.py"), regenerate=True),
    Target("servo_joints_to_units (template)", "templates/servo_map.c.j2",
           (("mark", r"^static uint16_t to_units", r"^    return true;"),),
           (SAFETY_LAYERS, "tests/test_servo_map.py"), regenerate=True),
    Target("servo_joints_to_units (model)", "model/servo.py",
           (("py", "units_per_rad"), ("py", "joint_to_units"), ("py", "units_to_joint"), ("py", "unit_range")),
           (SAFETY_LAYERS, "tests/test_servo_map.py"), regenerate=True),
    Target("IK selection (template)", "templates/kinematics.c.j2",
           (("mark", r"^    int best = -1;", r"^    return best;"),
            ("mark", r"^    kin_status_t first_reason", r"^    return first_reason;")),
           ("tests/test_kin_ik.py", SAFETY_LAYERS), regenerate=True),
    Target("app.c: command guards", "firmware_stm32/App/Src/app.c",
           (("c", "app_next_goal"), ("c", "command_servos"), ("c", "on_set_position"), ("c", "not_ready"),
            ("c", "on_engage")),
           ("tests/test_bad_ik.py", "tests/test_command_guards.py", "tests/test_hardening.py", "tests/test_app.py")),
    Target("app.c: fault watches", "firmware_stm32/App/Src/app.c",
           (("c", "imu_usable"), ("c", "imu_stale_tick"), ("c", "sample_imu"), ("c", "tick"), ("c", "app_watch"),
            ("c", "app_poll")),
           ("tests/test_fault_timing.py", "tests/test_hardening.py", "tests/test_app.py")),
    Target("servo_track.c: tracking watch", "firmware_stm32/App/Src/servo_track.c",
           (("c", "tracks"), ("c", "look_at_servo"), ("c", "track_update")),
           ("tests/test_fault_timing.py", "tests/test_fault_injection.py::test_stuck_servo_is_flagged_the_arm_parks_and_recovers",
            "tests/test_fault_injection.py::test_drifting_servo_is_flagged_the_arm_parks_and_recovers",
            "tests/test_fault_injection.py::test_sluggish_but_healthy_servos_are_not_flagged")),
    Target("llcp.c: LLCP receiver", "firmware_stm32/App/Src/llcp.c",
           (("c", "hex_value"), ("c", "llcp_rx_poll"), ("c", "finish"), ("c", "llcp_rx_byte")),
           ("tests/test_llcp.py", "tests/test_fault_timing.py")),
    Target("dxl_protocol.c: status parser", "firmware_stm32/App/Src/dxl_protocol.c",
           (("c", "dxl_checksum"), ("c", "candidate"), ("c", "drop_front"), ("c", "dxl_parse_byte")),
           ("tests/test_dxl_protocol.py", "tests/test_servo_bus.py")),
    Target("motion.c: swept motion", "firmware_stm32/App/Src/motion.c",
           (("c", "largest_change"), ("c", "path_clear"), ("c", "aim_clear"), ("c", "motion_start"),
            ("c", "goal_from"), ("c", "motion_goal_for"), ("c", "tuck_route"), ("c", "motion_go"),
            ("c", "motion_on_axis"), ("c", "motion_head_for"), ("c", "leg_offset"), ("c", "clear_of_legs"),
            ("c", "follow"), ("c", "motion_tick"), ("c", "motion_smaller")),
           ("tests/test_motion_planner.py", "tests/test_motion.py", "tests/test_service.py", "tests/test_command_guards.py",
            "tests/test_bad_ik.py", "tests/test_app.py", "tests/test_safety_grid.py")),
    Target("app.c: service and recovery", "firmware_stm32/App/Src/app.c",
           (("c", "service_refusal"), ("c", "torque_on"), ("c", "on_torque"), ("c", "jog_pose"), ("c", "on_jog"),
            ("c", "on_stream"), ("c", "in_service"), ("c", "end_service"), ("c", "drone_heard"), ("c", "link_silent"),
            ("c", "watch_link"), ("c", "watch_resets"), ("c", "start_motion"), ("c", "hold_faults"), ("c", "head_for"),
            ("c", "go_limp"), ("c", "on_enable"), ("c", "set_enabled")),
           ("tests/test_service.py", "tests/test_bench_enable.py", "tests/test_hardening.py", "tests/test_command_guards.py",
            "tests/test_app.py")),
    Target("servo_bus.c: servo bus", "firmware_stm32/App/Src/servo_bus.c",
           (("c", "forget_servo_state"), ("c", "sbus_power"), ("c", "sbus_command"), ("c", "sbus_limp"),
            ("c", "note_error_byte"), ("c", "receive_direct"), ("c", "receive_resync"), ("c", "configure"),
            ("c", "take_status"), ("c", "build_refit"), ("c", "sync_fill"), ("c", "run")),
           ("tests/test_servo_bus.py", "tests/test_service.py", "tests/test_hardening.py",
            "tests/test_fault_injection.py", "tests/test_fault_timing.py")),
    Target("stabiliser.c: gyro bias at rest", "firmware_stm32/App/Src/stabiliser.c", (("c", "bias_at_rest"),),
           tuple(f"tests/test_quaternion.py::test_{name}" for name in (
               "a_second_at_rest_measures_the_whole_gyro_bias", "no_bias_is_taken_while_the_board_moves",
               "the_stillness_threshold_is_half_a_degree_per_second", "a_jolt_starts_the_window_again",
               "gyro_bias_is_learnt_at_rest", "a_vibrating_accelerometer_is_not_still",
               "each_second_at_rest_measures_the_bias_again"))
           + tuple(f"tests/test_velocity_aiding.py::test_{name}" for name in (
               "on_the_ground_the_split_waits_for_the_velocity_to_settle_then_learns",
               "a_still_board_standing_tilted_levels_where_the_velocity_held_it"))),
    Target("stabiliser.c: the drone's messages", "firmware_stm32/App/Src/stabiliser.c",
           (("c", "stream_fresh"), ("c", "history_at"), ("c", "admit"), ("c", "take"), ("c", "move_fc_error"),
            ("c", "stab_drone_attitude"), ("c", "shift_velocity"), ("c", "stab_drone_velocity")),
           ("tests/test_velocity_aiding.py", "tests/test_quaternion.py", "tests/test_drone_gate.py")),
    Target("stabiliser.c: the drone messages' gate", "firmware_stm32/App/Src/stabiliser.c",
           (("c", "heard_lately"), ("c", "stab_sources"), ("c", "hear"), ("c", "distrust"), ("c", "judge"),
            ("c", "drift_gate"), ("c", "corrected"), ("c", "restart_velocity"), ("c", "velocity_gate2")),
           ("tests/test_drone_gate.py", "tests/test_velocity_aiding.py", "tests/test_quaternion.py")),
    Target("stabiliser.c: the estimate's sample", "firmware_stm32/App/Src/stabiliser.c", (("c", "stab_sample"),),
           ("tests/test_velocity_aiding.py", "tests/test_quaternion.py", "tests/test_estimator.py")),
    Target("velocity aiding (model)", "model/velocity.py",
           (("py", "predict"), ("py", "innovation"), ("py", "along_up"), ("py", "accel_bias_update"),
            ("py", "turned"), ("py", "gains"), ("py", "accel_bias_gains")),
           ("tests/test_velocity_aiding.py", "tests/test_model_config.py"), regenerate=True),
    Target("app.c: watchdog health", "firmware_stm32/App/Src/app.c", (("c", "app_healthy"),),
           ("tests/test_fault_timing.py::test_the_watchdog_is_fed_only_while_ticks_run_and_the_clock_moves",
            "tests/test_fault_timing.py::test_a_stalled_clock_starves_the_watchdog")),
    Target("motion.c: follow", "firmware_stm32/App/Src/motion.c", (("c", "follow"),),
           ("tests/test_motion_planner.py",)),
    Target("board_guard.c: reset cause and fault record", "firmware_stm32/Board/Src/board_guard.c",
           (("c", "reset_cause"), ("c", "board_guard_start"), ("c", "board_fault")),
           ("tests/test_board_guard.py",)),
    Target("calibrate/fit.py: gyro scale", "uavarm/calibrate/fit.py",
           (("py", "turned"), ("py", "_up_misfit"), ("py", "fit_gyro_scale")),
           ("tests/test_calibrate.py",)),
)

# Never run against a mutant: they compare generated/ with the generator's output, which
# would kill a template or model mutant without any behaviour being checked.
FRESHNESS_TESTS = ("tests/test_codegen.py", "tests/test_cli.py::test_codegen_check_passes_through")
