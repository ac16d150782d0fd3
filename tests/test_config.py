from __future__ import annotations

import json

import pytest

from odmd_bench import ConfigError, GeneratorConfig
from odmd_bench.data.config import HSR_GRASP_CAMERA, PRESETS, CameraConfig, get_preset


def test_presets_follow_the_paper() -> None:
    odmd = PRESETS["odmd"]
    assert odmd.camera == HSR_GRASP_CAMERA
    assert (odmd.camera.fx, odmd.camera.cx, odmd.camera.cy) == (205.5, 320.5, 240.5)
    assert odmd.move_min == (0.0, 0.0, 0.05) and odmd.move_max == (0.25, 0.175, 0.325)
    assert odmd.object_size == (0.01, 0.175) and odmd.initial_depth == (0.55, 1.0)
    odms = PRESETS["odms"]
    assert odms.move_max == (0.0, 0.0, 0.4625) and odms.camera.fx == odms.camera.fy == 240.5


def test_configs_are_frozen() -> None:
    with pytest.raises(AttributeError):
        PRESETS["odmd"].n_obs = 3  # type: ignore[misc]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"n_obs": 1}, "n_obs"),
        ({"object_size": (0.2, 0.1)}, "object_size"),
        ({"move_min": (0.3, 0.0, 0.05)}, "move_min[0]"),
        ({"initial_depth": (0.3, 1.0)}, "initial_depth[0]"),
        ({"replace_prob": 1.5}, "replace_prob"),
        ({"box_sigma": -1.0}, "box_sigma"),
        ({"camera_sigma": float("nan")}, "camera_sigma"),
    ],
)
def test_bad_values_name_the_field(change: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        GeneratorConfig.from_dict(change)
    assert field in info.value.render()


def test_view_bound_is_the_exact_supplementary_condition() -> None:
    # Just below the smallest Z1_min that keeps an s_max object in view for y.
    need = 0.325 + (2 * 0.175 + 0.175) * 205.5 / 480
    GeneratorConfig(initial_depth=(need + 1e-9, 1.0))
    with pytest.raises(ConfigError, match="too close for the y axis"):
        GeneratorConfig(initial_depth=(need - 1e-6, 1.0))


def test_unknown_keys_are_errors_at_both_levels() -> None:
    with pytest.raises(ConfigError, match="unknown key 'n_observations'"):
        GeneratorConfig.from_dict({"n_observations": 10})
    with pytest.raises(ConfigError, match="unknown key 'camera.focal'"):
        GeneratorConfig.from_dict({"camera": {"focal": 1.0}})


def test_camera_validation() -> None:
    with pytest.raises(ConfigError, match="camera.cx"):
        CameraConfig(image_width=640, image_height=480, fx=200.0, fy=200.0, cx=700.0, cy=240.0)


@pytest.mark.parametrize("suffix", [".json", ".yaml", ".yml"])
def test_round_trip_through_files(tmp_path, suffix: str) -> None:
    for name, cfg in PRESETS.items():
        path = tmp_path / f"{name}{suffix}"
        cfg.write(path)
        assert GeneratorConfig.from_file(path) == cfg


def test_partial_file_takes_defaults_and_bad_files_are_clear(tmp_path) -> None:
    p = tmp_path / "c.json"
    p.write_text(json.dumps({"n_obs": 5}))
    assert GeneratorConfig.from_file(p).n_obs == 5
    p.write_text("{not json")
    with pytest.raises(ConfigError, match="not valid JSON"):
        GeneratorConfig.from_file(p)
    with pytest.raises(ConfigError, match="cannot read"):
        GeneratorConfig.from_file(tmp_path / "missing.yaml")
    with pytest.raises(ConfigError, match="unknown configuration format"):
        (tmp_path / "c.txt").write_text("n_obs: 5")
        GeneratorConfig.from_file(tmp_path / "c.txt")


def test_unknown_preset() -> None:
    with pytest.raises(ConfigError, match="odmd, odms"):
        get_preset("kitti")


def test_a_yaml_alias_bomb_is_refused_before_it_expands(tmp_path) -> None:
    # 9 levels of 9 aliases: 387 million strings if expanded (the message would print them).
    levels = ['&a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    levels += [f"&a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
    p = tmp_path / "bomb.yaml"
    p.write_text("\n".join(f"k{i}: {level}" for i, level in enumerate(levels)) + "\nn_obs: *a8\n")
    with pytest.raises(ConfigError, match="anchors"):
        GeneratorConfig.from_file(p)


def test_a_config_file_names_every_problem(tmp_path) -> None:
    p = tmp_path / "c.yaml"
    p.write_text(
        "n_obs: 1\nobject_size: [0.2, 0.1]\ninitial_depth: [-1, 1]\n1: 2\nfoo: 3\ncamera: {fx: -5}\n"
    )
    with pytest.raises(ConfigError) as info:
        GeneratorConfig.from_file(p)
    text = info.value.render()
    assert "key 1 is not a name" in text and "unknown key 'foo'" in text  # mixed keys: no TypeError
    p.write_text("n_obs: 1\nobject_size: [0.2, 0.1]\ninitial_depth: [-1, 1]\ncamera: {fx: -5}\n")
    with pytest.raises(ConfigError) as info:
        GeneratorConfig.from_file(p)
    text = info.value.render()
    for words in (
        "n_obs: expected an integer from 2 to 1000",
        "object_size: need",
        "initial_depth: need",
        "fx/fy",
    ):
        assert words in text
    p.write_bytes(b"n_obs: \xff\n")
    with pytest.raises(ConfigError, match="not UTF-8"):
        GeneratorConfig.from_file(p)
    with pytest.raises(ConfigError, match="n_obs: expected an integer from 2 to 1000, got 1000000000"):
        GeneratorConfig.from_dict({"n_obs": 10**9})
    with pytest.raises(ConfigError, match="too large to print"):
        GeneratorConfig.from_dict({"n_obs": 10**5000})
