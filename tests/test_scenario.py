import pytest

from maskless.diagrams.scenario import load_scenario
from maskless.errors import ConfigError


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
