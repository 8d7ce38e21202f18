"""Scenarios: shipped defaults, YAML overrides and tags, shorthands; errors name file and field."""

import numpy as np
import pytest
import yaml

from maskless.diagrams.scenario import (
    IdentifiedPlant,
    cameras_measured_by,
    controller_from_shorthand,
    load_scenario,
    plant_from_shorthand,
    shorthand,
)
from maskless.diagrams.simulation import simulate
from maskless.errors import ConfigError
from maskless.recording import read_recording
from maskless.systems.config_loading import asset_path
from maskless.systems.sensing.depth_sensor import KinectV2Config


def test_shipped_defaults_are_complete_and_valid(config):
    assert config.duration_s == 120.0
    assert config.cameras["kinect_v2"].mount_height_m == 0.90
    assert config.paper.lqr_R == 0.058006  # from assets/paper.yaml, as printed


def test_user_file_overrides_only_what_it_names(tmp_path):
    path = tmp_path / "user.yaml"
    path.write_text("cameras:\n  kinect_v1:\n    latency_s: 0.2\npaper:\n  lqr_R: 0.1\n")
    config = load_scenario(path)
    assert config.cameras["kinect_v1"].latency_s == 0.2
    assert config.cameras["kinect_v1"].frame_rate_hz == 15.0
    assert config.paper.lqr_R == 0.1
    assert config.paper.A == [[0.0, 1.0], [-0.9883, 1.988]]


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "cameras:\n  kinect_v1:\n    latency_ms: 0.1\n",
            r"unknown field 'cameras\.kinect_v1\.latency_ms'",
        ),
        (
            "cameras:\n  kinect_v2:\n    dropout_probability: 1.5\n",
            r"cameras\.kinect_v2\.dropout_probability = 1\.5",
        ),
        (
            "cameras:\n  kinect_v1:\n    latency_s: 0.01\n",
            r"cameras\.kinect_v1\.latency_s = 0\.01: expected at least half a frame",
        ),
        ("duration_s: -1\n", r"duration_s = -1"),
        (
            "patient_motion:\n  enabled: true\n  shift_std_m: -0.002\n",
            r"patient_motion\.shift_std_m = -0\.002",
        ),
        (
            "cameras:\n  kinect_v1:\n    rendering:\n      enabled: true\n"
            "      vertical_fov_deg: 190.0\n",
            r"cameras\.kinect_v1\.rendering\.vertical_fov_deg = 190\.0: expected an angle",
        ),
        (
            "cameras:\n  kinect_v2:\n    rendering:\n      enabled: true\n      color_scale: 0\n",
            r"cameras\.kinect_v2\.rendering\.color_scale = 0",
        ),
        (
            "cameras:\n  kinect_v2:\n    rendering:\n      enabled: true\n"
            "      position_m: [0.1]\n",
            r"cameras\.kinect_v2\.rendering\.position_m = \[0\.1\]: expected \[x, y\]",
        ),
        ("camera_image_rate_hz: 0\n", r"camera_image_rate_hz = 0"),
        ("reference:\n  step_times_s: [1.0, 2.0]\n", r"step_offsets_m has 1"),
        (
            "reference:\n  step_times_s: [3.0]\n  step_offsets_m: [0.0]\n"
            "metrics:\n  tolerance_m: 0\n",
            r"metrics\.tolerance_m",
        ),
    ],
)
def test_bad_user_file_is_refused_naming_file_and_field(tmp_path, text, message):
    path = tmp_path / "user.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as raised:
        load_scenario(path)
    assert "user.yaml" in str(raised.value)


THIRD_CAMERA = """
cameras:
  kinect_v3: !KinectV2Config
    mount_height_m: 0.95
    frame_rate_hz: 15.0
    latency_s: 0.0667
    dropout_probability: 0.0
    incidence_angle_rad: 0.3
    min_range_m: 0.5
    max_range_m: 4.5
    warmup_drift_m: 0.0
    warmup_time_constant_s: 300.0
    warmup_elapsed_s: 1200.0
    resolution_m: 0.001
"""


def test_a_third_camera_is_one_yaml_entry_and_is_fused_with_the_others(tmp_path):
    path = tmp_path / "three.yaml"
    path.write_text(THIRD_CAMERA + "duration_s: 5.0\n")
    scenario = load_scenario(path)
    assert list(scenario.cameras) == ["kinect_v1", "kinect_v2", "kinect_v3"]
    assert isinstance(scenario.cameras["kinect_v2"], KinectV2Config)  # untouched entries kept
    run = simulate(scenario)
    assert run.signals["kinect_v3.valid"].values[0].mean() > 0.9
    # Eq. 10 over all three tracks: the fused information is the sum of the local ones.
    local = [run.signals[f"kinect_v{k}_filter.covariance"].values[:, -1] for k in (1, 2, 3)]
    information = sum(np.linalg.inv(P.reshape(2, 2)) for P in local)
    fused = run.signals["fusion.covariance"].values[:, -1].reshape(2, 2)
    np.testing.assert_allclose(fused, np.linalg.inv(information), rtol=1e-9)
    recording = read_recording(run.write_mcap(tmp_path / "run.mcap"))
    assert "/sensors/kinect_v3/measurement" in recording.messages
    assert "/filters/kinect_v3/estimate" in recording.messages


def write_first_order_model(path):
    """A first-order model of the head height (m) from the inlet current (A).

    As `maskless identify` writes one: DC gain 0.1 m/A about 0.2 m and 0.1 A.
    """
    contents = {
        "A": [[0.98]],
        "B": [[0.002]],
        "C": [[1.0]],
        "D": [[0.0]],
        "K": [[0.5]],
        "sample_period_s": 1.0 / 15.0,
        "input": {"unit": "A", "offset": 0.1},
        "output": {"unit": "m", "offset": 0.2},
    }
    path.write_text(yaml.safe_dump(contents))
    return path


def test_a_tagged_identified_plant_runs_that_model(tmp_path):
    model = write_first_order_model(tmp_path / "model.yaml")
    path = tmp_path / "identified.yaml"
    path.write_text(f"plant: !IdentifiedPlant {{model_file: {model}}}\nduration_s: 30.0\n")
    scenario = load_scenario(path)
    assert scenario.plant == IdentifiedPlant(model_file=str(model))
    run = simulate(scenario)
    assert run.closed_loop.plant == "identified"
    head = run.signals["head_height_m"].values[0] - 0.2
    inlet = run.signals["inlet_valve_current_a"].values[0] - 0.1
    # The logs obey the model file's own equation, x+ = 0.98 x + 0.002 u (deviations, m and A),
    # tick by tick, and the offset-free LQG holds the head at the 5 mm step.
    np.testing.assert_allclose(head[1:], 0.98 * head[:-1] + 0.002 * inlet[:-1], atol=1e-15)
    settled = run.signals["head_height_m"].times_s > 20.0
    assert head[settled].mean() == pytest.approx(0.005, abs=3e-4)


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "plant: !IdentifedPlant {model_file: m.yaml}\n",
            r"'plant' has the tag !IdentifedPlant; "
            r"expected one of !PneumaticPlant, !PaperPlant, !IdentifiedPlant",
        ),
        (
            "plant: identified:m.yaml\n",
            r"field 'plant' = 'identified:m.yaml': expected a mapping "
            r"tagged with one of",
        ),
        (
            "plant: !IdentifiedPlant {model: m.yaml}\n",
            r"unknown field 'plant\.model' \(did you "
            r"mean 'plant\.model_file'\?\)",
        ),
        (
            "cameras:\n  kinect_v1: !KinectV3Config {}\n",
            r"'cameras\.kinect_v1' has the tag "
            r"!KinectV3Config",
        ),
        ("duration_s: !Seconds 3\n", r"'duration_s' has the tag !Seconds, but takes no tag"),
        (
            "plant: !IdentifiedPlant {model_file: none.yaml}\n",
            r"plant\.model_file = 'none\.yaml': "
            r"model file not found",
        ),
        (
            "cameras:\n  kinect_v3: !KinectV1Config {frame_rate_hz: 15.0}\n",
            r"fields not set: cameras\.kinect_v3\.mount_height_m",
        ),
        ("controller: !PaperLqg {camera: kinect_v9}\n", r"controller\.camera = 'kinect_v9'"),
    ],
)
def test_a_malformed_tag_or_choice_is_refused_naming_file_and_field(tmp_path, text, message):
    path = tmp_path / "tagged.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as raised:
        load_scenario(path)
    assert "tagged.yaml" in str(raised.value)


def test_an_untagged_override_keeps_the_camera_model_it_overrides(tmp_path):
    # yaml_load_typed alone would read an untagged entry as the Union's first type (Kinect v1).
    path = tmp_path / "v2.yaml"
    path.write_text("cameras:\n  kinect_v2:\n    latency_s: 0.1333\n")
    camera = load_scenario(path).cameras["kinect_v2"]
    assert isinstance(camera, KinectV2Config) and camera.latency_s == 0.1333
    assert camera.resolution_m == 0.001


@pytest.mark.parametrize("text", ["pneumatic", "paper", "identified:m.yaml"])
def test_plant_shorthands_round_trip(text):
    assert shorthand(plant_from_shorthand(text)) == text


@pytest.mark.parametrize("text", ["offset-free-lqg", "offset-free-lqg:m.yaml", "paper-lqg"])
def test_controller_shorthands_round_trip(text):
    assert shorthand(controller_from_shorthand(text)) == text


def test_an_override_that_breaks_the_scenario_names_the_override():
    with pytest.raises(ConfigError, match=r"overrides \(duration_s\): duration_s = -1"):
        load_scenario(duration_s=-1.0)
    with pytest.raises(ConfigError, match="unknown scenario field 'duration'"):
        load_scenario(duration=3.0)


def test_a_choice_set_as_a_string_is_refused_naming_the_variants():
    expected = "field 'controller' = 'paper-lqg': expected one of OffsetFreeLqg, PaperLqg"
    with pytest.raises(ConfigError, match=expected):
        load_scenario(controller="paper-lqg")


@pytest.mark.parametrize(
    "overrides, message",
    [
        ({"duration_s": "30"}, r"field 'duration_s' = '30': expected a number"),
        ({"random_seed": 1.5}, r"field 'random_seed' = 1.5: expected an integer"),
        ({"cameras": {"a": 3}}, r"cameras\.a' = 3: expected one of KinectV1Config"),
        ({"cameras": {"kinéct": None}}, r"cameras\.kinéct: expected a name of ASCII letters"),
        ({"cameras": {"fusion": None}}, r"cameras\.fusion: the closed loop has a system"),
    ],
)
def test_an_override_of_the_wrong_type_or_name_is_refused(config, overrides, message):
    if "cameras" in overrides:  # a real camera model under a bad name
        camera = next(iter(config.cameras.values()))
        overrides = {"cameras": {k: v or camera for k, v in overrides["cameras"].items()}}
    with pytest.raises(ConfigError, match=message):
        load_scenario(**overrides)


def test_sensors_flag_form_renders_every_camera_or_none(config):
    rendered = cameras_measured_by(config.cameras, rendered=True)
    assert all(camera.rendering.enabled for camera in rendered.values())
    assert not any(camera.rendering.enabled for camera in config.cameras.values())  # a copy
    modelled = cameras_measured_by(rendered, rendered=False)
    assert not any(camera.rendering.enabled for camera in modelled.values())


def test_a_rendered_camera_needs_its_rendering_settings_a_modelled_one_does_not(tmp_path):
    path = tmp_path / "three.yaml"
    path.write_text(THIRD_CAMERA)
    assert not load_scenario(path).cameras["kinect_v3"].rendering.enabled
    path.write_text(THIRD_CAMERA + "    rendering:\n      enabled: true\n")
    with pytest.raises(ConfigError, match=r"cameras\.kinect_v3\.rendering\.image_width_px"):
        load_scenario(path)


def test_a_shipped_preset_by_name_is_its_file_applied_before_the_config(tmp_path):
    from maskless.diagrams.scenario import scenario_preset_names

    assert "paper_camera_noise" in scenario_preset_names()
    assert not any(name.startswith("population_") for name in scenario_preset_names())
    by_name = load_scenario(presets=["paper_camera_noise"])
    by_file = load_scenario(asset_path("presets/paper_camera_noise.yaml"))
    assert by_name == by_file
    over = tmp_path / "over.yaml"
    over.write_text("cameras:\n  kinect_v1:\n    error:\n      white_noise_std_m: 0.001\n")
    both = load_scenario(over, presets=["paper_camera_noise"])
    assert both.cameras["kinect_v1"].error.white_noise_std_m == 0.001  # the file wins
    assert both.cameras["kinect_v2"].error == by_name.cameras["kinect_v2"].error
    with pytest.raises(
        ConfigError,
        match="no scenario preset 'paper'; shipped: noisy_pressure_sensor, paper_camera",
    ):
        load_scenario(presets=["paper"])


# --- plausibility limits: refused before anything runs, with the field, the cap and the reason ---


@pytest.mark.parametrize(
    "text, message",
    [
        ("duration_s: 1.0e+12\n", r"duration_s = 1000000000000\.0: expected 0 to 86400 s \(.*GB"),
        ("duration_s: 1.0e-9\n", r"duration_s = 1e-09: expected at least one controller tick"),
        (
            "cameras:\n  kinect_v1: !KinectV1Config {latency_s: 100.0}\n",
            r"cameras\.kinect_v1\.latency_s = 100\.0: expected 0 to 1 s \(.*latency",
        ),
        (
            "cameras:\n  kinect_v2: !KinectV2Config {frame_rate_hz: 1.0e+6}\n",
            r"cameras\.kinect_v2\.frame_rate_hz = 1000000\.0: expected 1 to 1000 Hz",
        ),
        ("camera_image_rate_hz: 1.0e+6\n", r"camera_image_rate_hz = 1000000\.0: expected 0 to 30"),
        ("pneumatic: {head_mass_kg: 0.001}\n", r"pneumatic\.head_mass_kg = 0\.001: expected 1 to"),
        (
            "reference: {step_times_s: [10.0], step_offsets_m: [10.0]}\n",
            r"reference\.step_offsets_m = \[10\.0\]: 10\.0 is out of reach.*\[-0\.008, 0\.04\]",
        ),
        (
            "plant: !PaperPlant {}\ncontroller: !PaperLqg {}\n"
            "reference: {step_times_s: [10.0], step_offsets_m: [-0.05]}\n",
            r"reference\.step_offsets_m = \[-0\.05\]: -0\.05 is out of reach.*travel, \+-0\.048",
        ),
    ],
)
def test_an_implausible_scenario_is_refused_with_the_cap_and_reason(tmp_path, text, message):
    path = tmp_path / "implausible.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as raised:
        load_scenario(path)
    assert str(raised.value).startswith(f"{path}: ") and "\n" not in str(raised.value)


def test_an_unstable_model_cannot_play_the_plant(tmp_path):
    model = write_first_order_model(tmp_path / "model.yaml")
    model.write_text(model.read_text().replace("0.98", "1.02"))
    with pytest.raises(ConfigError, match=r"plant\.model_file = .*unstable .*1\.02"):
        load_scenario(plant=IdentifiedPlant(model_file=str(model)))
