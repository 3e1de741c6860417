"""Config dataclasses check every field when built (``ambulo.utils.validate``), issue 22 item 4.

The rules are tested on small configs written here; then the package's own configs: every one is
``Checked``, all their defaults (and every registered task's env, play and PPO configs) pass, and
every number field of every config refuses NaN in one line that names it.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import math
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pytest

from ambulo.utils.checks import InvalidValueError
from ambulo.utils.validate import UNCHECKED, Checked, check_fields, rule
from one_line import raises_one_line

SRC = Path(__file__).resolve().parents[2] / "src" / "ambulo"


@dataclass(kw_only=True)
class _Inner(Checked):
    timestep_s: float = 0.005


@dataclass(kw_only=True)
class _Cfg(Checked):
    episode_length_s: float = 20.0
    rate_hz: float | None = None
    goal_radius_m: float = 0.1
    z_m: float = 0.0
    standing_fraction: float = 0.1
    range_noise_std_m: float = 0.0
    push_velocity_m_s: float = 0.5
    friction_range: tuple[float, float] | None = (0.4, 1.2)
    lin_vel_x_m_s: tuple[float, float] = field(default=(-1.0, 1.0), metadata=rule(pair=True))
    resampling_time_s: tuple[float, float] = field(default=(4.0, 8.0), metadata=rule(pair=True))
    settle_s: float = field(default=1.0, metadata=rule(minimum=0.0))
    action_clip: float = field(default=100.0, metadata=rule(finite=False))
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    num_frames: int = 10
    decimation: int = field(default=4, metadata=rule(minimum=1))
    seed: int = 0
    nice: int = field(default=5, metadata=rule(signed=True))
    hidden_dims: tuple[int, ...] = (64, 64)
    shadows: bool = False
    mode: Literal["fast", "exact"] = "fast"
    weights: dict[str, float] = field(default_factory=dict)
    anything: object = None
    judged_elsewhere_s: float = field(default=-1.0, metadata=UNCHECKED)
    inner: _Inner = field(default_factory=_Inner)


def test_defaults_and_legitimate_values_pass():
    _Cfg()
    _Cfg(z_m=-3.0, lin_vel_x_m_s=(-2.0, -1.0), friction_range=(1.0, 1.0), range_noise_std_m=0.0,
         push_velocity_m_s=-0.5, settle_s=0.0, action_clip=math.inf, seed=-7, nice=-5, rate_hz=50,
         episode_length_s=np.float32(5.0), num_frames=np.int64(3), shadows=np.bool_(True),
         weights={"alive": -2.0}, gravity=[0.0, 0.0, -1.62])
    _Cfg(friction_range=None)


@pytest.mark.parametrize("kwargs, parts", [
    ({"episode_length_s": -5.0}, ("_Cfg.episode_length_s is -5.0", "a duration must be > 0",
                                  "pass seconds, e.g. episode_length_s=20.0")),
    ({"episode_length_s": 0.0}, ("episode_length_s is 0.0", "must be > 0")),
    ({"episode_length_s": math.inf}, ("episode_length_s is inf", "a duration must be finite", "pass seconds")),
    ({"episode_length_s": math.nan}, ("episode_length_s is nan", "must be finite")),
    ({"episode_length_s": "20"}, ("episode_length_s is '20'", "expected a real number, got str")),
    ({"episode_length_s": 1 + 2j}, ("expected a real number, got complex",)),
    ({"episode_length_s": True}, ("expected a real number, got bool",)),
    ({"rate_hz": 0.0}, ("_Cfg.rate_hz is 0.0", "a rate must be > 0", "pass Hz")),
    ({"goal_radius_m": -0.1}, ("goal_radius_m is -0.1", "a length must be >= 0", "pass metres, e.g. goal_radius_m=0.1")),
    ({"z_m": math.inf}, ("z_m is inf", "must be finite")),
    ({"standing_fraction": 1.5}, ("standing_fraction is 1.5", "must be in [0, 1]", "pass a number in [0, 1]")),
    ({"range_noise_std_m": -0.1}, ("range_noise_std_m is -0.1", "a noise level must be >= 0", "0: none")),
    ({"friction_range": (1.2, 0.4)}, ("friction_range is (1.2, 0.4)", "the low end is above the high end",
                                      "pass (low, high) with low <= high (or None), e.g. friction_range=(0.4, 1.2)")),
    ({"friction_range": (0.4, math.nan)}, ("friction_range is (0.4, nan)", "must be finite")),
    ({"friction_range": (0.4,)}, ("expected 2 values, got 1",)),
    ({"lin_vel_x_m_s": (1.0, -1.0)}, ("lin_vel_x_m_s is (1.0, -1.0)", "the low end is above the high end")),
    ({"resampling_time_s": (-1.0, 8.0)}, ("resampling_time_s is (-1.0, 8.0)", "a duration must be > 0")),
    ({"settle_s": -1.0}, ("settle_s is -1.0", "a duration must be >= 0")),
    ({"action_clip": math.nan}, ("action_clip is nan", "must be finite")),
    ({"gravity": (0.0, 0.0)}, ("gravity is (0.0, 0.0)", "expected 3 values, got 2")),
    ({"gravity": "down"}, ("gravity is 'down'", "expected 3 values, got str")),
    ({"num_frames": 2.5}, ("num_frames is 2.5", "expected a whole number, got float", "e.g. num_frames=10")),
    ({"num_frames": -1}, ("num_frames is -1", "it must be >= 0")),
    ({"decimation": 0}, ("decimation is 0", "it must be >= 1", "e.g. decimation=4")),
    ({"hidden_dims": (64, -1)}, ("hidden_dims is (64, -1)", "it must be >= 0")),
    ({"shadows": "false"}, ("shadows is 'false'", "expected true or false", "pass True or False")),
    ({"mode": "quick"}, ("mode is 'quick'", "not one of its choices", "pass one of 'fast', 'exact'")),
    ({"weights": {"alive": math.nan}}, ("_Cfg.weights is {'alive': nan}", "must be finite")),
    ({"inner": _Inner(timestep_s=0.01)}, ()),
])
def test_a_bad_field_is_refused_in_one_line_naming_it_and_the_fix(kwargs, parts):
    if not parts:  # a valid nested config
        _Cfg(**kwargs)
        return
    raises_one_line(lambda: _Cfg(**kwargs), *parts)


def test_nested_configs_are_checked_when_built_and_again_by_check_fields():
    raises_one_line(lambda: _Inner(timestep_s=-1.0), "_Inner.timestep_s is -1.0")
    cfg = _Cfg()
    cfg.inner.timestep_s = -1.0  # edited after it was built
    raises_one_line(lambda: check_fields(cfg), "_Inner.timestep_s is -1.0", "pass seconds")
    cfg = _Cfg()
    cfg.episode_length_s = -5.0
    raises_one_line(lambda: check_fields(cfg), "_Cfg.episode_length_s is -5.0")


def test_dataclasses_replace_checks_too():
    raises_one_line(lambda: dataclasses.replace(_Cfg(), episode_length_s=-5.0), "episode_length_s is -5.0")


# --- the package's configs --------------------------------------------------------------------


def _config_classes() -> list[tuple[str, str]]:
    """(module, class) of every dataclass in the package named *Cfg, *Config or *Settings."""
    found = []
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in tree.body:
            if (isinstance(node, ast.ClassDef) and node.name.endswith(("Cfg", "Config", "Settings"))
                    and any("dataclass" in ast.unparse(d) for d in node.decorator_list)):
                module = ".".join(path.relative_to(SRC.parent).with_suffix("").parts)
                found.append((module, node.name))
    return found


CONFIGS = _config_classes()


def _import(module: str, name: str):
    return getattr(importlib.import_module(module), name)


def test_the_package_has_configs_to_check():
    names = {name for _, name in CONFIGS}
    assert {"EnvCfg", "PhysicsCfg", "PpoCfg", "VelocityCommandCfg", "DatasetConfig", "CameraCfg"} <= names


@pytest.mark.parametrize("module, name", CONFIGS, ids=[name for _, name in CONFIGS])
def test_every_config_dataclass_is_checked(module, name):
    assert issubclass(_import(module, name), Checked), f"{module}.{name} is not a Checked config"


def _required(cls) -> dict:
    """Values for the fields of ``cls`` without a default (a prim path, a robot file, ...)."""
    from ambulo.core import RobotCfg
    from ambulo.locomotion.balance import FootShape
    from ambulo.locomotion.preview import PreviewControlCfg
    from ambulo.sensors import CameraCfg

    given = {
        "file": "robot.xml", "prim_path": "/World/sensor", "prim_paths": ("/World/robot/foot",),
        "prims": "/World/box*", "joints": ".*", "region": ((-1.0, 1.0), (-1.0, 1.0)),
        "length_m": 0.22, "width_m": 0.1, "com_height_m": 0.8, "single_support_s": 0.6,
        "double_support_s": 0.2, "swing_height_m": 0.05, "build_scene": lambda: None,
        "preview": PreviewControlCfg(com_height_m=0.8), "foot": FootShape(length_m=0.22, width_m=0.1),
        "targets": ["/World/box"], "kinds": {}, "colors": None, "base": {}, "surfaces": ["/World/floor"],
        "robot": RobotCfg(file="robot.xml"), "step_lengths_m": (0.0, 0.2), "step_widths_m": (0.2,),
        "step_yaws_rad": (0.0,),
    }
    out = {}
    for f in dataclasses.fields(cls):
        if f.init and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            if f.name == "camera":
                out[f.name] = "/World/camera" if cls.__name__ == "CameraJitter" else CameraCfg(prim_path="/World/cam")
            else:
                out[f.name] = given[f.name]
    return out


def _checked_classes() -> list[type]:
    """Every ``Checked`` config of the package (the named configs, and randomizers and the
    Isaac Replicator nodes, which are configs too)."""
    for module, name in CONFIGS:
        _import(module, name)
    importlib.import_module("ambulo.replicator.scatter")
    importlib.import_module("ambulo.isaac.replicator.nodes")
    seen, todo = [], [Checked]
    while todo:
        for sub in todo.pop().__subclasses__():
            if sub not in seen and sub.__module__.startswith("ambulo."):
                seen.append(sub)
                todo.append(sub)
    return sorted(seen, key=lambda c: c.__name__)


CHECKED = _checked_classes()


@pytest.mark.parametrize("cls", CHECKED, ids=[c.__name__ for c in CHECKED])
def test_each_config_builds_with_its_defaults_and_refuses_nan_in_every_number(cls):
    cfg = cls(**_required(cls))
    hints = typing.get_type_hints(cls)
    numbers = [f.name for f in dataclasses.fields(cls)
               if f.init and hints[f.name] in (float, float | None, int, int | None)]
    for name in numbers:
        bad = math.nan if hints[name] in (float, float | None) else 0.5
        with pytest.raises(InvalidValueError) as info:
            dataclasses.replace(cfg, **{name: bad})
        assert name in str(info.value) and "\n" not in str(info.value)


def test_every_registered_task_config_passes_its_own_checks():
    from ambulo import envs

    for name in envs.names():
        spec = envs.spec(name)
        for cfg in (spec.cfg_fn(), spec.play_cfg(), spec.ppo_cfg_fn()):
            check_fields(cfg)


@pytest.mark.parametrize("cfg_path", ["ambulo.envs.ppo:PpoCfg", "ambulo.rl.offpolicy.config:OffPolicyCfg"])
@pytest.mark.parametrize("name, bad", [("gamma", 1.5), ("gamma", -0.1), ("num_envs", 0)])
def test_learning_settings_outside_their_meaning_are_refused(cfg_path, name, bad):
    # a discount above 1 makes returns diverge, and 0 worlds train nothing; both trained silently
    module, cls_name = cfg_path.split(":")
    cls = getattr(importlib.import_module(module), cls_name)
    with pytest.raises(InvalidValueError) as info:
        cls(**{name: bad})
    assert name in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("name, bad", [("learning_rate", -1.0), ("learning_rate", 0.0), ("lam", 1.2),
                                       ("clip_param", 0.0), ("desired_kl", -0.01), ("num_mini_batches", 0),
                                       ("num_learning_epochs", 0), ("entropy_coef", -0.01),
                                       ("init_noise_std", 0.0), ("max_grad_norm", 0.0)])
def test_ppo_settings_outside_their_meaning_are_refused(name, bad):
    # learning_rate=-1 reached torch's optimizer as a traceback; gamma=1.5 and lam=1.2 trained silently
    from ambulo.envs.ppo import PpoCfg

    with pytest.raises(InvalidValueError) as info:
        PpoCfg(**{name: bad})
    assert name in str(info.value) and "\n" not in str(info.value)
