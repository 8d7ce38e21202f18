"""The safety supervisor, tick by tick: each check latches its reason and takes its safe action."""

import dataclasses
import math

import numpy as np
import pytest

from maskless.errors import ConfigError
from maskless.systems.control.safety_supervisor import (
    MODES,
    REASONS,
    SAFE_ACTIONS,
    SafetyConfig,
    make_safety_supervisor,
    safety_states,
    validate_safety,
)
from tests.system_harness import port_layout
from tests.test_pressure_pace_check import CONFIG as PACE_CHECK
from tests.test_shut_inlet_check import CONFIG as SHUT_INLET_CHECK

PERIOD_S = 0.1
LOW_M, HIGH_M = 0.200, 0.230
TOLERANCE_M = 0.001
INLET_FULL_A, OUTLET_FULL_A = 0.165, 0.170
CONFIG = SafetyConfig(
    enabled=True,
    start_grace_s=0.25,
    travel_margin_m=0.005,
    max_gauge_pressure_pa=15_000.0,
    max_full_inlet_s=1.0,
    disagreement_persist_s=0.3,
    estimate_margin_m=0.0003,
    fused_error_band_m=0.0012,
    beam_dwell_s=0.3,
    hold_time_constant_s=2.0,
    pressure_pace=PACE_CHECK,
    shut_inlet=SHUT_INLET_CHECK,
)
PACE = CONFIG.pressure_pace
SHUT = CONFIG.shut_inlet
# A healthy loop at rest on its reference, two cameras used.
HEALTHY = {
    "inlet_command_a": 0.100,
    "outlet_command_a": 0.010,
    "fused_estimated_state": [0.215, 0.0],
    "fusion_health": [2.0, 0.0, 0.0],
    "reference_head_height_m": 0.215,
    "estimated_head_height_m": 0.215,
    "bladder_gauge_pressure_pa": 3000.0,
    "reset": 0.0,
}


class Supervisor:
    """The supervisor built alone, stepped one tick at a time with the inputs given."""

    def __init__(self, config=CONFIG, period_s=PERIOD_S):
        self.period_s = period_s
        self.system = make_safety_supervisor(
            config,
            period_s=period_s,
            camera_count=2,
            head_height_limits_m=(LOW_M, HIGH_M),
            tolerance_m=TOLERANCE_M,
            inlet_saturation_a=INLET_FULL_A,
            outlet_saturation_a=OUTLET_FULL_A,
        )
        self.context = self.system.CreateDefaultContext()
        self.set(**HEALTHY)

    def set(self, **inputs):
        for name, value in inputs.items():
            self.system.GetInputPort(name).FixValue(self.context, np.atleast_1d(value))

    def tick(self, ticks=1, **inputs):
        self.set(**inputs)
        for _ in range(ticks):
            update = self.system.EvalUniquePeriodicDiscreteUpdate(self.context)
            self.context.get_mutable_discrete_state().SetFrom(update)
            self.context.SetTime(self.context.get_time() + self.period_s)

    def out(self, name):
        return self.system.GetOutputPort(name).Eval(self.context)

    def latched(self):
        return {r for r, on in zip(REASONS, self.out("reasons"), strict=True) if on > 0.5}

    def mode(self):
        return MODES[int(self.out("mode")[0])]

    def valves(self):
        return self.out("inlet_valve_current_a")[0], self.out("outlet_valve_current_a")[0]


def test_ports():
    inputs, outputs = port_layout(Supervisor().system)
    assert inputs == {
        "inlet_command_a": 1,
        "outlet_command_a": 1,
        "fused_estimated_state": 2,
        "fusion_health": 3,
        "reference_head_height_m": 1,
        "estimated_head_height_m": 1,
        "bladder_gauge_pressure_pa": 1,
        "reset": 1,
    }
    assert outputs == {
        "inlet_valve_current_a": 1,
        "outlet_valve_current_a": 1,
        "reasons": len(REASONS),
        "mode": 1,
        "beam_hold": 1,
    }


def test_a_healthy_loop_passes_its_commands_bit_for_bit_and_latches_nothing():
    s = Supervisor()
    for inlet in (0.1, 0.123456789, 0.0, INLET_FULL_A - 1e-9):
        s.tick(inlet_command_a=inlet)
        assert s.valves() == (inlet, HEALTHY["outlet_command_a"])
    assert s.latched() == set() and s.mode() == "pass"


def test_the_held_currents_are_an_exponential_average_of_the_healthy_commands():
    s = Supervisor()
    commands = [0.10, 0.12, 0.08, 0.11, 0.09]
    held = commands[0]  # the average starts at the first command
    s.tick(inlet_command_a=commands[0])
    weight = 1 - math.exp(-PERIOD_S / CONFIG.hold_time_constant_s)
    for command in commands[1:]:
        s.tick(inlet_command_a=command)
        held += weight * (command - held)
    # No camera: hold. The tick that sees it still averages its command, computed a tick before.
    s.tick(fusion_health=[0.0, 0.0, 0.0])
    held += weight * (commands[-1] - held)
    assert s.mode() == "hold"
    assert s.valves()[0] == pytest.approx(held, rel=1e-12)
    assert s.valves()[1] == pytest.approx(HEALTHY["outlet_command_a"], rel=1e-12)


@pytest.mark.parametrize(
    "inputs, reason",
    [
        ({"fusion_health": [1.0, 0.0, 0.0]}, "camera_excluded"),
        ({"fusion_health": [0.0, 0.0, 0.0]}, "no_camera"),
        ({"fusion_health": [2.0, 0.0, 1.0]}, "estimate_uncertain"),
        ({"fused_estimated_state": [HIGH_M + 0.0051, 0.0]}, "outside_travel"),
        ({"fused_estimated_state": [LOW_M - 0.0051, 0.0]}, "outside_travel"),
        ({"fused_estimated_state": [math.nan, 0.0]}, "outside_travel"),
        ({"outlet_command_a": math.inf}, "non_finite_command"),
        ({"bladder_gauge_pressure_pa": 15_000.1}, "overpressure"),
        ({"bladder_gauge_pressure_pa": math.nan}, "overpressure"),
    ],
)
def test_each_check_latches_its_reason_and_takes_its_action_until_reset(inputs, reason):
    s = Supervisor()
    s.tick(3)  # past the start grace
    s.tick(**inputs)
    # A pressure beyond its limit is also a jump in its pace (one that reads no number is none);
    # any other check latches alone.
    jumped = reason == "overpressure" and math.isfinite(inputs["bladder_gauge_pressure_pa"])
    assert s.latched() == ({reason, "pressure_jump"} if jumped else {reason})
    expected = {"continue": "pass", "hold": "hold", "vent": "vent"}[SAFE_ACTIONS[reason]]
    assert s.mode() == expected
    assert s.out("beam_hold")[0] == 1.0
    s.tick(**HEALTHY)  # the cause is gone: the reason stays latched
    assert reason in s.latched() and s.out("beam_hold")[0] == 1.0
    s.tick(reset=1.0)
    s.tick(reset=0.0)
    assert s.latched() == set() and s.mode() == "pass"


def test_just_inside_each_limit_nothing_latches():
    s = Supervisor()
    s.tick(3)
    s.tick(outlet_command_a=999.0)  # a big number is still a number
    # The pressure follows a tick later (the change of command explains its step).
    s.tick(fused_estimated_state=[HIGH_M + 0.0049, 0.0], bladder_gauge_pressure_pa=14_999.0)
    assert s.latched() == set()


def test_the_estimate_checks_wait_for_the_start_grace():
    s = Supervisor()
    s.tick(2, fusion_health=[0.0, 0.0, 1.0])  # t = 0, 0.1: within the 0.25 s grace
    assert s.latched() == set()
    s.tick(2)  # t = 0.2, 0.3
    assert s.latched() == {"no_camera", "estimate_uncertain"}


def test_a_non_finite_command_is_replaced_at_once_by_the_held_currents():
    s = Supervisor()
    s.tick(3)
    s.set(inlet_command_a=math.nan)  # no tick yet: the same instant
    inlet, outlet = s.valves()
    assert inlet == pytest.approx(HEALTHY["inlet_command_a"]) and math.isfinite(inlet)
    assert outlet == pytest.approx(HEALTHY["outlet_command_a"])
    assert s.out("beam_hold")[0] == 1.0


def test_overpressure_vents_the_bladder():
    s = Supervisor()
    s.tick(3)
    s.tick(bladder_gauge_pressure_pa=20_000.0)
    assert s.mode() == "vent" and s.valves() == (0.0, OUTLET_FULL_A)


def test_the_inlet_fully_open_for_too_long_latches_at_its_limit():
    s = Supervisor()
    ticks = round(CONFIG.max_full_inlet_s / PERIOD_S)
    s.tick(ticks - 1, inlet_command_a=INLET_FULL_A)
    assert s.latched() == set()
    s.tick()
    assert s.latched() == {"inlet_full_too_long"}


def _on_a_steady_pace(pace_pa: float, ticks: int = 60) -> tuple[Supervisor, float]:
    """A supervisor on a pressure rising ``pace_pa`` a tick, and the last pressure.

    The rise lasts long enough for the tracker to follow it exactly, and the commands have been
    steady so long that their first change has faded (0.11 A x 0.7^25 x 5 kPa/A = 7e-2 Pa).
    """
    s = Supervisor()
    s.tick(25)
    pressure = HEALTHY["bladder_gauge_pressure_pa"]
    for _ in range(ticks):
        pressure += pace_pa
        s.tick(bladder_gauge_pressure_pa=pressure)
    return s, pressure


@pytest.mark.parametrize("step_pa", [80.0, 140.0])
def test_a_step_with_steady_commands_latches_a_jump_when_its_sum_passes_the_alarm(step_pa):
    s, pressure = _on_a_steady_pace(5.0)
    assert s.latched() == set()
    # The tracker coasts from the step on, so each tick's residual is the step; the sum after k
    # ticks is k (step - drift), a jump from the first k above the alarm (the faded command
    # change adds a hundredth of a pascal to the drift).
    per_tick = step_pa - PACE.drift_pa
    ticks = math.floor(PACE.alarm_pa / per_tick) + 1
    for _ in range(ticks - 1):
        pressure += 5.0
        s.tick(bladder_gauge_pressure_pa=pressure + step_pa)
    assert s.latched() == set()
    s.tick(bladder_gauge_pressure_pa=pressure + 5.0 + step_pa)
    assert s.latched() == {"pressure_jump"} and s.mode() == "pass"
    assert s.valves() == (HEALTHY["inlet_command_a"], HEALTHY["outlet_command_a"])


def test_a_step_within_the_drift_is_never_a_jump():
    s, pressure = _on_a_steady_pace(5.0)
    for _ in range(100):
        pressure += 5.0
        s.tick(bladder_gauge_pressure_pa=pressure + 0.99 * PACE.drift_pa)
    assert s.latched() == set()


def test_a_moving_bladders_pace_changes_are_its_own_dynamics():
    # Tracked at 30 Pa a tick, beyond the still pace: its changes are not judged.
    s, pressure = _on_a_steady_pace(30.0)
    for pace in (90.0, 25.0, 100.0):
        pressure += pace
        s.tick(bladder_gauge_pressure_pa=pressure)
    assert "pressure_jump" not in s.latched()


def test_a_step_the_commands_explain_is_the_loop_at_work():
    # The inlet moved 20 mA a tick before the pressure stepped (a command reaches the pressure at
    # the next tick): 5000 Pa/A x 0.02 A = 100 Pa more is forgiven, fading by 0.7 a tick, while
    # the tracker follows the new level. The same step with steady commands is a jump.
    for inlet, latched in ((0.120, set()), (HEALTHY["inlet_command_a"], {"pressure_jump"})):
        s, pressure = _on_a_steady_pace(0.0)
        s.tick(inlet_command_a=inlet)
        s.tick(10, bladder_gauge_pressure_pa=pressure + 139.0)
        assert s.latched() == latched, inlet


SHUT_TICKS = math.ceil(SHUT.hold_s / PERIOD_S - 1e-9)


def test_a_shut_inlet_that_keeps_the_pressure_latches_after_its_hold():
    # Shut at one tick, the command reaches the reading at the next, which notes the level the
    # pressure must fall from; the hold's last tick finds it has not fallen.
    s = Supervisor()
    s.tick(25)
    s.tick(SHUT_TICKS, inlet_command_a=0.0)
    assert s.latched() == set()
    s.tick()
    assert s.latched() == {"inlet_not_shut"} and s.mode() == "pass"
    assert s.valves() == (0.0, HEALTHY["outlet_command_a"])
    assert s.out("beam_hold")[0] == 1.0


@pytest.mark.parametrize("fall_fraction, latched", [(1.1, set()), (0.9, {"inlet_not_shut"})])
def test_a_shut_inlet_passes_while_the_pressure_falls_by_its_least_fall(fall_fraction, latched):
    # On a steady fall the tracker follows exactly: over the hold's ticks after the noted one
    # the level falls (hold ticks - 1) x the fall per tick.
    fall_pa = fall_fraction * SHUT.min_fall_pa / (SHUT_TICKS - 1)
    s, pressure = _on_a_steady_pace(-fall_pa)
    for _ in range(40):
        pressure -= fall_pa
        s.tick(inlet_command_a=0.0, bladder_gauge_pressure_pa=pressure)
    assert pressure > SHUT.min_pressure_pa
    assert s.latched() == latched


def test_a_stuck_inlet_after_a_long_shut_stretch_is_judged_a_window_later():
    # Three windows of a healthy fall (1.5 times the least fall), then the pressure holds with
    # the inlet still shut: the window after the fall stopped latches, none before.
    fall_pa = 1.5 * SHUT.min_fall_pa / (SHUT_TICKS - 1)
    s, pressure = _on_a_steady_pace(-fall_pa)
    for _ in range(3 * SHUT_TICKS):
        pressure -= fall_pa
        s.tick(inlet_command_a=0.0, bladder_gauge_pressure_pa=pressure)
    assert s.latched() == set()
    s.tick(2 * SHUT_TICKS, inlet_command_a=0.0, bladder_gauge_pressure_pa=pressure)
    assert s.latched() == {"inlet_not_shut"}


def test_a_shut_inlet_is_judged_from_a_tracked_level_not_the_zero_state():
    # No grace and no least pressure: the check still waits for the tracker's level, so a
    # healthy fall from the first tick is no alarm (the zero state is no level to fall from).
    config = dataclasses.replace(
        CONFIG,
        start_grace_s=0.0,
        shut_inlet=dataclasses.replace(SHUT, min_pressure_pa=0.0),
    )
    s = Supervisor(config)
    pressure = HEALTHY["bladder_gauge_pressure_pa"]
    for _ in range(5 * SHUT_TICKS):
        pressure -= 30.0
        s.tick(inlet_command_a=0.0, bladder_gauge_pressure_pa=pressure)
    assert s.latched() == set()


def test_an_empty_bladder_with_its_inlet_shut_is_the_head_at_rest():
    s = Supervisor()
    s.tick(25, bladder_gauge_pressure_pa=0.99 * SHUT.min_pressure_pa)
    s.tick(100, inlet_command_a=0.0)
    assert s.latched() == set()


def test_an_inlet_that_opens_again_restarts_the_hold():
    s = Supervisor()
    s.tick(25)
    for _ in range(3):  # one tick short of the hold, counting the command's tick to the reading
        s.tick(SHUT_TICKS - 1, inlet_command_a=0.0)
        s.tick(inlet_command_a=0.001)
    assert s.latched() == set()
    s.tick(SHUT_TICKS + 1, inlet_command_a=0.0)
    assert s.latched() == {"inlet_not_shut"}


def test_a_shut_inlet_is_not_judged_while_the_supervisor_holds_the_air():
    s = Supervisor()
    s.tick(25)
    s.tick(fusion_health=[0.0, 0.0, 0.0])
    assert s.latched() == {"no_camera"} and s.mode() == "hold"
    s.tick(3 * SHUT_TICKS, inlet_command_a=0.0)
    assert s.latched() == {"no_camera"}


def test_the_beam_waits_for_the_dwell_and_drops_the_instant_the_error_grows():
    s = Supervisor()
    assert s.out("beam_hold")[0] == 1.0  # a fresh supervisor holds the beam
    dwell_ticks = math.ceil(CONFIG.beam_dwell_s / PERIOD_S - 1e-9)
    s.tick(dwell_ticks - 1)
    assert s.out("beam_hold")[0] == 1.0
    s.tick()
    assert s.out("beam_hold")[0] == 0.0
    band = TOLERANCE_M - CONFIG.estimate_margin_m
    s.set(estimated_head_height_m=0.215 + band * 1.01)  # no tick: the output sees it at once
    assert s.out("beam_hold")[0] == 1.0
    s.set(estimated_head_height_m=0.215, fused_estimated_state=[0.215 - 0.00121, 0.0])
    assert s.out("beam_hold")[0] == 1.0
    s.set(fused_estimated_state=[0.215 - 0.00119, 0.0])
    assert s.out("beam_hold")[0] == 0.0


def test_safety_states_names_the_state_and_the_reasons():
    reasons = np.zeros((len(REASONS), 4))
    reasons[REASONS.index("camera_excluded"), 1:] = 1
    reasons[REASONS.index("no_camera"), 2:] = 1
    mode = np.array([0.0, 0.0, 1.0, 2.0])
    states, names = safety_states(mode, reasons)
    assert list(states) == ["normal", "degraded", "holding", "venting"]
    assert list(names) == ["", "camera_excluded", "camera_excluded,no_camera"] + [
        "camera_excluded,no_camera"
    ]


@pytest.mark.parametrize(
    "field, value",
    [
        ("max_gauge_pressure_pa", 0.0),
        ("max_full_inlet_s", math.inf),
        ("estimate_margin_m", TOLERANCE_M),
        ("beam_dwell_s", -1.0),
        ("fused_error_band_m", math.nan),
        ("pressure_pace.per_current_pa_per_a", -0.1),
        ("pressure_pace.level_gain", 2.0),
        ("pressure_pace.alarm_pa", 0.0),
        ("shut_inlet.min_fall_pa", -5.0),
    ],
)
def test_a_limit_out_of_range_is_refused_by_name(field, value):
    section, _, name = field.rpartition(".")
    if section:
        changed = dataclasses.replace(getattr(CONFIG, section), **{name: value})
        config = dataclasses.replace(CONFIG, **{section: changed})
    else:
        config = dataclasses.replace(CONFIG, **{field: value})
    with pytest.raises(ConfigError, match=f"safety.{field} = "):
        validate_safety(config, TOLERANCE_M)


def test_a_disagreement_holds_the_beam_at_once_and_the_air_if_it_persists():
    s = Supervisor()
    s.tick(round(CONFIG.beam_dwell_s / PERIOD_S) + 3)
    assert s.out("beam_hold")[0] == 0.0
    s.set(fusion_health=[2.0, 1.0, 0.0])
    assert s.out("beam_hold")[0] == 1.0  # no tick yet
    ticks = round(CONFIG.disagreement_persist_s / PERIOD_S)
    s.tick(ticks - 1)
    assert s.latched() == set() and s.mode() == "pass"
    s.tick()
    assert s.latched() == {"cameras_disagree"} and s.mode() == "hold"


def test_a_disagreement_ended_by_a_camera_left_out_lets_the_loop_go_on():
    s = Supervisor()
    s.tick(3)
    s.tick(2, fusion_health=[2.0, 1.0, 0.0])
    s.tick(5, fusion_health=[1.0, 0.0, 0.0])  # the fusion left the wrong camera out
    assert s.latched() == {"camera_excluded"} and s.mode() == "pass"


def test_a_non_finite_command_leaves_the_pressure_check_whole_after_a_reset():
    for bad in ({"inlet_command_a": math.nan}, {"outlet_command_a": math.inf}):
        s = Supervisor()
        s.tick(25)
        s.tick(**bad)
        assert "non_finite_command" in s.latched()
        s.tick(**{**HEALTHY, "reset": 1.0})
        s.tick(reset=0.0)
        s.tick(25)  # a still loop: nothing to latch
        assert s.latched() == set(), bad
        s.tick(bladder_gauge_pressure_pa=3000.0 + 2000.0)  # and a jump is still caught
        assert "pressure_jump" in s.latched(), bad


def test_a_reset_clears_only_what_passes_now():
    s = Supervisor()
    s.tick(3)
    s.tick(bladder_gauge_pressure_pa=20_000.0, fusion_health=[1.0, 0.0, 0.0])
    assert {"overpressure", "camera_excluded"} <= s.latched() and s.mode() == "vent"
    s.tick(fusion_health=[2.0, 0.0, 0.0], reset=1.0)  # the pressure is still too high
    assert "overpressure" in s.latched() and "camera_excluded" not in s.latched()
    assert s.mode() == "vent" and s.valves() == (0.0, OUTLET_FULL_A)


def test_no_pressure_jump_before_there_is_a_pace_to_compare_even_without_a_grace():
    s = Supervisor(dataclasses.replace(CONFIG, start_grace_s=0.0))
    s.tick(5)
    assert s.latched() == set()


def test_limits_that_are_no_whole_number_of_ticks_round_up():
    period_s = 1 / 15
    s = Supervisor(dataclasses.replace(CONFIG, beam_dwell_s=0.5), period_s=period_s)
    s.tick(7)  # 0.5 s is 7.5 ticks: 8
    assert s.out("beam_hold")[0] == 1.0
    s.tick()
    assert s.out("beam_hold")[0] == 0.0


def test_the_average_starts_at_the_first_command_it_keeps():
    s = Supervisor()
    s.tick(inlet_command_a=INLET_FULL_A)  # fully open: not kept
    s.tick(10, inlet_command_a=0.1)
    s.tick(fusion_health=[0.0, 0.0, 0.0])
    s.tick()
    assert s.mode() == "hold" and s.valves()[0] == pytest.approx(0.1, rel=1e-12)
