"""A run's logged signals as recording channels: which Drake log feeds which MCAP topic and field.

The closed loop logs its exported output ports (``diagrams.closed_loop.export_and_log``) by port
name; these functions turn those logs, a whole run's or a chunk's, into the ``Channel`` columns
``maskless.recording`` writes. A field is named after its port (a state estimate's two components
after what they estimate; see ``maskless.recording``).
"""

import numpy as np

from maskless.diagrams.closed_loop import Signal
from maskless.recording import (
    BLADDER_PRESSURE_TOPIC,
    COMMAND_TOPIC,
    FUSION_TOPIC,
    HEAD_HEIGHT_TOPIC,
    REFERENCE_TOPIC,
    SAFETY_TOPIC,
    Channel,
    filter_estimate_topic,
    sensor_measurement_topic,
)
from maskless.systems.control.safety_supervisor import safety_states


def _nanoseconds(times_s: np.ndarray) -> np.ndarray:
    return np.round(times_s * 1e9).astype(np.int64)


def _estimate_channel(topic: str, state: Signal, covariance: Signal) -> Channel:
    return Channel(
        topic,
        _nanoseconds(state.times_s),
        {
            "head_height_m": state.values[0],
            "head_velocity_m_s": state.values[1],
            "covariance": covariance.values.T.reshape(-1, 2, 2),
        },
    )


def signal_channels(s: dict[str, Signal], sensor_names: list[str]) -> list[Channel]:
    """Logged signals (a whole run's or a chunk's) as MCAP channels."""
    channels = [
        Channel(
            REFERENCE_TOPIC,
            _nanoseconds(s["reference_head_height_m"].times_s),
            {"reference_head_height_m": s["reference_head_height_m"].values[0]},
        ),
        Channel(
            HEAD_HEIGHT_TOPIC,
            _nanoseconds(s["head_height_m"].times_s),
            {"head_height_m": s["head_height_m"].values[0]},
        ),
    ]
    for name in sensor_names:
        distance, valid = s[f"{name}.distance_m"], s[f"{name}.valid"]
        channels.append(
            Channel(
                sensor_measurement_topic(name),
                _nanoseconds(distance.times_s),
                {"distance_m": distance.values[0], "valid": valid.values[0] > 0.5},
            )
        )
    for name in sensor_names:
        channels.append(
            _estimate_channel(
                filter_estimate_topic(name),
                s[f"{name}_filter.estimated_state"],
                s[f"{name}_filter.covariance"],
            )
        )
    channels.append(
        _estimate_channel(FUSION_TOPIC, s["fusion.estimated_state"], s["fusion.covariance"])
    )
    channels.append(
        Channel(
            COMMAND_TOPIC,
            _nanoseconds(s["inlet_valve_current_a"].times_s),
            {
                "inlet_valve_current_a": s["inlet_valve_current_a"].values[0],
                "outlet_valve_current_a": s["outlet_valve_current_a"].values[0],
            },
        )
    )
    if "safety.beam_hold" in s:
        channels.append(_safety_channel(s))
    if "plant.bladder_gauge_pressure_pa" in s:
        pressure = s["plant.bladder_gauge_pressure_pa"]
        channels.append(
            Channel(
                BLADDER_PRESSURE_TOPIC,
                _nanoseconds(pressure.times_s),
                {"gauge_pressure_pa": pressure.values[0]},
            )
        )
    return channels


def _safety_channel(s: dict[str, Signal]) -> Channel:
    """The supervisor's state, latched reasons and beam hold at each tick (``/safety/status``)."""
    states, reasons = safety_states(s["safety.mode"].values[0], s["safety.reasons"].values)
    return Channel(
        SAFETY_TOPIC,
        _nanoseconds(s["safety.beam_hold"].times_s),
        {
            "state": states,
            "reasons": reasons,
            "beam_hold": s["safety.beam_hold"].values[0] > 0.5,
            "estimated_head_height_m": s["safety.estimated_head_height_m"].values[0],
            "inlet_valve_current_a": s["safety.inlet_valve_current_a"].values[0],
            "outlet_valve_current_a": s["safety.outlet_valve_current_a"].values[0],
        },
    )
