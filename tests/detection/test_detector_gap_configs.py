"""The domain-gap benchmark's configs: each factor split moves only its randomizer, and the generic
training config adds variety without reaching into split (b)'s ranges (the split must stay unseen)."""

import dataclasses
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from ambulo import replicator as rep

GAP_FILE = Path(__file__).resolve().parents[2] / "benchmarks" / "detect_domain_gap.py"


@pytest.fixture(scope="module")
def gap():
    spec = importlib.util.spec_from_file_location("detect_domain_gap", GAP_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def by_name(cfg: rep.DatasetConfig) -> dict:
    return {r.name: r for r in cfg.randomizers}


def test_each_factor_split_moves_only_its_randomizer(gap):
    example, unseen = by_name(rep.example_config(64, 48)), by_name(gap.config(64, 48))
    for factor, moved in gap.FACTORS.items():
        one = by_name(gap.config(64, 48, (factor,)))
        assert one.keys() == example.keys()
        assert [n for n in one if one[n] != example[n]] == [moved], factor
        assert one[moved] == unseen[moved]
    assert [n for n in unseen if unseen[n] != example[n]] == sorted(gap.FACTORS.values(), key=list(unseen).index)


def test_generic_training_data_stays_outside_the_unseen_split(gap):
    train, example, unseen = by_name(gap.training_config(64, 48)), by_name(rep.example_config(64, 48)), \
        by_name(gap.config(64, 48))
    # lights and camera exactly the example's: split (b)'s lighting and heights stay unseen
    assert train["lights"] == example["lights"] and train["camera_jitter"] == example["camera_jitter"]
    # distractors: more of the same kind, not split (b)'s pool, sizes or counts
    d, e, u = train["distractors"], example["distractors"], unseen["distractors"]
    assert d.pool_size > e.pool_size and d.pool_seed == e.pool_seed != u.pool_seed
    assert d.size_m == e.size_m and d.count == e.count and d.size_m[1] < u.size_m[1]
    assert dataclasses.replace(d, pool_size=e.pool_size) == e
    # textures: a larger palette of the training seed, never split (b)'s
    seeds = {r.palette_seed for r in train.values() if isinstance(r, rep.MaterialRandomizer)}
    assert unseen["object_materials"].palette_seed not in seeds
    assert train["object_materials"].untextured_probability == example["object_materials"].untextured_probability


def test_hard_negatives_are_class_families_outside_the_classes_and_split_b(gap):
    from ambulo.replicator.hard_negatives import FAMILIES, class_shapes, shape_key, too_close

    train, example, unseen = by_name(gap.hard_negative_config(64, 48)), by_name(rep.example_config(64, 48)), \
        by_name(gap.config(64, 48))
    # the example scene's randomizers untouched: lights, camera heights, clutter and palette stay unseen ones
    assert all(train[name] == r for name, r in example.items())
    negatives = train["hard_negatives"]
    pool = negatives.pool()
    assert len(pool) == negatives.pool_size and {kind for kind, _ in pool} == set(FAMILIES)
    # split (b)'s pool is what its Distractors build: the shapes it draws, read back from the scene
    b = unseen["distractors"]
    built = rep.build_warehouse_scene()
    b.build(built)
    model = built.compile()
    sizes = [model.geom_size[model.body(f"/World/distractors/distractor_{i}").geomadr[0]] for i in range(b.pool_size)]
    assert np.allclose([s for _, s, _ in b.pool()], sizes)
    assert negatives.excluded_pools == gap.split_b_pools()
    avoid = class_shapes() + gap.split_b_pools()[0]
    for kind, size in pool:
        assert not too_close(kind, size, avoid, negatives.margin), (kind, size)
        # some dimension more than the margin away from each class of its family (a check by hand)
        for other_kind, other in class_shapes():
            if other_kind == kind:
                ratio = [max(a / c, c / a) for a, c in zip(shape_key(kind, size), shape_key(kind, other))]
                assert max(ratio) >= 1 + negatives.margin
    # the classes themselves are too close to themselves: the check can say no
    assert all(too_close(kind, size, class_shapes(), 0.25) for kind, size in class_shapes())


def built_pool(distractors) -> list[tuple[str, tuple, tuple]]:
    """(kind, size, rgb) of each geom ``distractors`` builds into the warehouse scene, read back from the model."""
    import mujoco

    spec = rep.build_warehouse_scene()
    distractors.build(spec)
    model = spec.compile()
    kinds = {int(getattr(mujoco.mjtGeom, f"mjGEOM_{k.upper()}")): k
             for k in ("box", "sphere", "cylinder", "capsule", "ellipsoid")}
    geoms = [model.body(f"/World/distractors/distractor_{i}").geomadr[0] for i in range(distractors.pool_size)]
    return [(kinds[int(model.geom_type[g])], tuple(model.geom_size[g]), tuple(model.geom_rgba[g][:3])) for g in geoms]


def test_split_b_clutter_holds_no_class_geometry(gap):
    """A split (b) distractor within 25 % of a class's geometry (the ball-sized spheres the old split drew) is
    redrawn: it would be a class by geometry, not clutter; every other shape and every colour stay as drawn."""
    from ambulo.replicator.hard_negatives import class_shapes, too_close
    from ambulo.replicator.scatter import Distractors

    b = by_name(gap.config(64, 48))["distractors"]
    as_distractors = Distractors(**{f.name: getattr(b, f.name) for f in dataclasses.fields(Distractors)})
    drawn, kept = built_pool(as_distractors), built_pool(b)
    twins = [i for i, (kind, size, _) in enumerate(drawn) if too_close(kind, size, class_shapes(), 0.25)]
    assert len(twins) == 3 and all(drawn[i][0] == "sphere" for i in twins)  # radii 0.147, 0.175, 0.181 m
    for i, ((kind, size, rgb), (kind_kept, size_kept, rgb_kept)) in enumerate(zip(drawn, kept)):
        assert kind_kept == kind and np.allclose(rgb_kept, rgb)
        assert not too_close(kind_kept, size_kept, class_shapes(), 0.25), (i, size_kept)
        assert np.allclose(size_kept, size) == (i not in twins)
        if kind == "sphere":  # by hand: > 25 % from both balls' radii
            assert all(max(size_kept[0] / r, r / size_kept[0]) >= 1.25 for r in (0.12, 0.18))
