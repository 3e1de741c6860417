"""``apply_overrides``: KEY=VALUE strings read as the annotated types of any dataclass."""

from __future__ import annotations  # string annotations, as in ambulo's configs

import enum
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from ambulo.utils.overrides import OverrideError, apply_overrides, parse_overrides, replace_dotted, type_name


class Mode(enum.Enum):
    FAST = 1
    SAFE = 2


@dataclass(frozen=True)
class Solver:
    iterations: int = 10
    kind: Literal["newton", "cg"] = "newton"


@dataclass(kw_only=True)
class Physics:
    dt_s: float = 0.005
    solver: Solver = field(default_factory=Solver)


@dataclass(kw_only=True)
class Cfg:
    num_envs: int = 64
    lr: float = 1e-3
    render: bool = False
    device: str = "cpu"
    schedule: Literal["adaptive", "fixed"] = "adaptive"
    level: Literal[1, 2, 3] = 1
    friction_range: tuple[float, float] = (0.4, 1.2)
    hidden_dims: tuple[int, ...] = (256, 128)
    feet: tuple[str, ...] = ("left_foot", "right_foot")
    gains: list[float] = field(default_factory=lambda: [1.0, 2.0])
    weights: dict[str, float] = field(default_factory=lambda: {"alive": 1.0, "torque": -1e-4})
    robot_file: str | None = None
    keyframe: str | None = "home"
    max_steps: int | None = 100
    mode: Mode = Mode.FAST
    out: Path = Path("runs")
    physics: Physics = field(default_factory=Physics)
    maybe_physics: Physics | None = None
    derived: int = field(default=0, init=False)


def one(text: str, cfg=None):
    return apply_overrides(cfg or Cfg(), [text])


def error(text: str, cfg=None) -> str:
    with pytest.raises(OverrideError) as caught:
        one(text, cfg)
    message = str(caught.value)
    assert "\n" not in message
    return message


# --- values read as their field's type ---------------------------------------------------


def test_int_float_str():
    cfg = apply_overrides(Cfg(), ["num_envs=512", "lr=3e-4", "device=cuda:0"])
    assert cfg.num_envs == 512 and type(cfg.num_envs) is int
    assert cfg.lr == 3e-4 and type(cfg.lr) is float
    assert cfg.device == "cuda:0"
    assert one("lr=2").lr == 2.0 and type(one("lr=2").lr) is float  # not the int 2
    assert one("device='cuda:1'").device == "cuda:1"  # quotes are optional
    assert one("device=123").device == "123"  # a str field keeps digits as text


@pytest.mark.parametrize("text, value", [("true", True), ("True", True), ("1", True),
                                         ("false", False), ("FALSE", False), ("0", False)])
def test_bool_words(text, value):
    assert one(f"render={text}").render is value


def test_literal_choices():
    assert one("schedule=fixed").schedule == "fixed"
    assert one("level=3").level == 3 and type(one("level=3").level) is int


def test_fixed_length_tuple_from_commas_or_parentheses():
    for text in ("0.1,0.2", "(0.1, 0.2)", "[0.1, 0.2]", " 0.1 , 0.2 "):
        value = one(f"friction_range={text}").friction_range
        assert value == (0.1, 0.2) and type(value) is tuple
    assert one("friction_range=1,2").friction_range == (1.0, 2.0)
    assert all(type(v) is float for v in one("friction_range=1,2").friction_range)


def test_variable_length_tuple_and_list():
    assert one("hidden_dims=64,64,32").hidden_dims == (64, 64, 32)
    assert one("hidden_dims=(32,)").hidden_dims == (32,)
    assert one("hidden_dims=32").hidden_dims == (32,)
    assert one("hidden_dims=()").hidden_dims == ()
    assert one("feet=a,b,c").feet == ("a", "b", "c")  # str elements need no quotes
    assert one("feet=('a,1', 'b')").feet == ("a,1", "b")  # ... unless they hold commas
    assert one("gains=3,4").gains == [3.0, 4.0]


def test_dict_from_a_literal():
    assert one("weights={'alive': 2, 'up': 0.5}").weights == {"alive": 2.0, "up": 0.5}
    assert type(one("weights={'alive': 2}").weights["alive"]) is float


def test_dict_entry_by_dotted_key():
    cfg = one("weights.alive=2.5")
    assert cfg.weights == {"alive": 2.5, "torque": -1e-4}
    assert Cfg().weights["alive"] == 1.0  # the default's dict is not changed in place


def test_optional_accepts_none():
    assert one("robot_file=/tmp/g1.xml").robot_file == "/tmp/g1.xml"
    assert one("keyframe=none").keyframe is None
    assert one("keyframe=None").keyframe is None
    assert one("max_steps=none").max_steps is None
    assert one("max_steps=7").max_steps == 7


def test_optional_nested_config_can_be_set_to_none():
    cfg = apply_overrides(Cfg(), ["maybe_physics=none"])
    assert cfg.maybe_physics is None
    with_physics = Cfg(maybe_physics=Physics())
    assert apply_overrides(with_physics, ["maybe_physics=none"]).maybe_physics is None
    assert apply_overrides(with_physics, ["maybe_physics.dt_s=0.01"]).maybe_physics.dt_s == 0.01


def test_enum_and_path():
    assert one("mode=SAFE").mode is Mode.SAFE
    assert one("out=/tmp/x").out == Path("/tmp/x")


def test_nested_dataclass_fields():
    cfg = apply_overrides(Cfg(), ["physics.dt_s=0.002", "physics.solver.iterations=50",
                                  "physics.solver.kind=cg"])
    assert cfg.physics.dt_s == 0.002
    assert cfg.physics.solver == Solver(iterations=50, kind="cg")
    assert Cfg().physics.solver.iterations == 10


def test_returns_a_new_instance_and_keeps_the_input():
    base = Cfg()
    new = apply_overrides(base, ["num_envs=8", "physics.solver.iterations=3"])
    assert new is not base and base == Cfg()
    assert new.physics is not base.physics
    assert apply_overrides(base, []) == base


def test_frozen_dataclass_works():
    assert apply_overrides(Solver(), ["iterations=4"]) == Solver(iterations=4)


def test_later_overrides_win_and_see_earlier_ones():
    assert apply_overrides(Cfg(), ["num_envs=1", "num_envs=2"]).num_envs == 2
    cfg = apply_overrides(Cfg(), ["weights={'a': 1.0}", "weights.a=3"])
    assert cfg.weights == {"a": 3.0}


def test_parse_overrides_and_replace_dotted_give_the_same_config():
    pairs = ["lr=0.01", "physics.solver.iterations=5", "weights.alive=0", "feet=x"]
    values = parse_overrides(Cfg(), pairs)
    assert values == {"lr": 0.01, "physics.solver.iterations": 5, "weights.alive": 0.0,
                      "feet": ("x",)}
    assert replace_dotted(Cfg(), values) == apply_overrides(Cfg(), pairs)


def test_type_names():
    assert type_name(tuple[float, float]) == "tuple[float, float]"
    assert type_name(tuple[int, ...]) == "tuple[int, ...]"
    assert type_name(dict[str, float]) == "dict[str, float]"
    assert type_name(int | None) == "int | none"
    assert type_name(Literal["a", "b"]) == "one of 'a', 'b'"


# --- errors: one line naming the key, the expected type, close matches -----------------------


def test_unknown_key_names_close_matches():
    message = error("num_env=3")
    assert "unknown key 'num_env'" in message and "Cfg" in message
    assert "did you mean 'num_envs'" in message


def test_unknown_key_without_close_match_lists_the_keys():
    message = error("zzzzzz=3")
    assert "valid keys:" in message and "num_envs" in message and "physics" in message


def test_unknown_nested_key_names_nested_close_matches():
    message = error("physics.solver.iteration=3")
    assert "'physics.solver.iteration'" in message and "Solver" in message
    assert "did you mean 'physics.solver.iterations'" in message


def test_init_false_field_is_not_a_key():
    assert "unknown key 'derived'" in error("derived=1")


def test_unknown_dict_entry():
    message = error("weights.aliv=2")
    assert "'weights.aliv'" in message and "did you mean 'weights.alive'" in message
    assert "its entries: alive, torque" in error("weights.zzzzz=2")
    assert "weights is empty" in error("weights.a=2", Cfg(weights={}))


@pytest.mark.parametrize("text, expected", [
    ("num_envs=1.5", "expected int"),
    ("num_envs=many", "expected int"),
    ("lr=fast", "expected float"),
    ("friction_range=(0.1, x)", "expected tuple[float, float]"),
    ("hidden_dims=a,b", "expected tuple[int, ...]"),
    ("weights=[1, 2]", "expected dict[str, float]"),
    ("weights={'a': 'b'}", "expected dict[str, float]"),
    ("max_steps=lots", "expected int | none"),
    ("keyframe=none", None),  # valid: checked below not to raise
])
def test_bad_value_names_key_and_type(text, expected):
    key, _, value = text.partition("=")
    if expected is None:
        one(text)
        return
    message = error(text)
    assert f"bad value {value!r} for {key}: {expected}" in message
    assert f"e.g. {key}=" in message  # the current value, as an example


def test_bad_bool_suggests_the_word():
    message = error("render=ture")
    assert "bad value 'ture' for render: expected bool (true/false/1/0)" in message
    assert "did you mean 'true'" in message
    assert "expected bool" in error("render=2")


def test_bad_literal_names_choices_and_close_match():
    message = error("schedule=adaptiv")
    assert "expected one of 'adaptive', 'fixed'" in message and "did you mean 'adaptive'" in message
    assert "expected one of 1, 2, 3" in error("level=4")


def test_bad_enum_names_members():
    message = error("mode=SAEF")
    assert "expected one of FAST, SAFE" in message and "did you mean 'SAFE'" in message


def test_wrong_tuple_length():
    for text in ("friction_range=0.1", "friction_range=1,2,3", "friction_range=(1, 2, 3)"):
        message = error(text)
        assert "expected tuple[float, float]" in message and "give 2 values" in message
        assert "e.g. friction_range=0.4,1.2" in message


def test_missing_equals_sign():
    message = error("num_envs")
    assert "expected KEY=VALUE, got 'num_envs'" in message
    assert "expected KEY=VALUE" in error("=3")


def test_setting_a_nested_config_whole_is_refused():
    message = error("physics=fast")
    assert "physics is a Physics" in message and "physics.dt_s" in message


def test_fields_of_a_plain_value_are_refused():
    message = error("num_envs.x=1")
    assert "num_envs is a single value (int)" in message


def test_fields_of_a_none_config_are_refused():
    message = error("maybe_physics.dt_s=0.1")
    assert "maybe_physics is none" in message


def test_error_carries_the_key():
    with pytest.raises(OverrideError) as caught:
        apply_overrides(Cfg(), ["num_envs=8", "physics.solver.iterations=x"])
    assert caught.value.key == "physics.solver.iterations"
    assert isinstance(caught.value, ValueError)


def test_not_a_dataclass_or_a_single_string():
    with pytest.raises(TypeError):
        apply_overrides({"a": 1}, ["a=2"])
    with pytest.raises(TypeError):
        apply_overrides(Cfg(), "num_envs=2")


def test_inf_is_a_float_but_nan_is_refused():
    assert math.isinf(one("lr=inf").lr)
    # NaN passes every `<` check a config makes, to crash a run later: refused at the boundary
    with pytest.raises(OverrideError, match=r"bad value 'nan' for lr: expected float; .*give a finite one"):
        one("lr=nan")


if False:  # a name only type checkers see, as under ``if TYPE_CHECKING:``
    from collections import OrderedDict


@dataclass
class PartlyResolvable:
    count: int = 1
    table: OrderedDict | None = None  # not resolvable at run time


def test_one_unresolvable_annotation_leaves_the_others_typed():
    cfg = apply_overrides(PartlyResolvable(), ["count=3", "table={'a': 1}"])
    assert cfg.count == 3 and type(cfg.count) is int
    assert cfg.table == {"a": 1}  # read as a Python literal
    assert "expected int" in error("count=x", PartlyResolvable())
