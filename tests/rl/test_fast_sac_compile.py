"""``OffPolicyCfg.compile`` (a walking task's default): a torch.compile failure at the first
update names the setting that turns it off; the recipe's defaults ask for it."""

import pytest

from ambulo.rl.offpolicy.config import offpolicy_cfg
from ambulo.rl.offpolicy.learner import compiled_step


def _failing_compile(fn):
    def built(batch):
        raise RuntimeError("Triton is not installed\nmore lines")
    return built


def test_a_compile_failure_names_the_setting_to_turn_it_off():
    step = compiled_step(lambda batch: None, "critic", compile_fn=_failing_compile)
    with pytest.raises(RuntimeError, match=r"compile of the critic update failed \(RuntimeError: Triton is "
                                           r"not installed\); train without it: `--algo-cfg compile=false`"):
        step(object())


def test_after_the_first_call_errors_are_the_updates_own():
    calls = []

    def update(batch):
        calls.append(batch)
        if len(calls) == 2:
            raise ValueError("a NaN in the critic loss")

    step = compiled_step(update, "actor", compile_fn=lambda fn: fn)
    step(1)
    with pytest.raises(ValueError, match="NaN"):  # passed through, not blamed on the compile
        step(2)
    assert calls == [1, 2]


@pytest.mark.parametrize("task", ["humanoid-walk", "g1-walk", "humanoid-rough", "g1-rough"])
def test_the_walking_recipe_compiles_its_graphed_updates(task):
    cfg = offpolicy_cfg(task, "fast-sac")
    assert cfg.compile and cfg.cuda_graph and cfg.batch_size == 8192 and cfg.updates_per_step == 8
    assert not offpolicy_cfg(task, "fast-td3").compile
