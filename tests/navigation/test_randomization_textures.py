"""Domain randomization of the apartments' looks (issue 24: "textures, lighting"): every procedural
texture is redrawn with its own contrast and brightness, every material's pattern scale changes,
the same seed replays it, and switched off nothing changes."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np

from ambulo.navigation.randomization import RandomizationCfg, Randomizer
from ambulo.robots import humanoid
from ambulo.scenes.apartment import apartment


def _randomized(seed: int, enabled: bool = True):
    spec = apartment(1010).build()
    before = {t.name: (t.file, spec.assets[t.file]) for t in spec.textures if t.file}
    repeats = {m.name: np.array(m.texrepeat, float) for m in spec.materials}
    cfg = RandomizationCfg(enabled=enabled)
    Randomizer(cfg, seed).edit_spec(spec, humanoid.PRIM_PATH)
    return spec, before, repeats, cfg


def test_textures_and_patterns_are_randomized_and_replayed():
    spec, before, repeats, cfg = _randomized(3)
    after = {t.name: (t.file, spec.assets[t.file]) for t in spec.textures if t.file}
    assert set(after) == set(before) and len(before) >= 10
    contrast_ratios = []
    for name, (file, png) in after.items():
        old_file, old_png = before[name]
        assert file != old_file and old_file not in spec.assets, "a redrawn texture needs a new asset name"
        old, new = (iio.imread(p).astype(float) for p in (old_png, png))
        contrast_ratios.append(new.std() / old.std())
    lo = cfg.texture_contrast_range[0] * cfg.texture_brightness_range[0]
    hi = cfg.texture_contrast_range[1] * cfg.texture_brightness_range[1]
    assert all(lo - 0.05 < r < hi + 0.05 for r in contrast_ratios), contrast_ratios
    assert np.ptp(contrast_ratios) > 0.2, "each texture draws its own contrast"
    scales = [float(np.array(m.texrepeat, float)[0] / repeats[m.name][0]) for m in spec.materials
              if repeats[m.name][0] > 0]
    assert all(cfg.texture_scale_range[0] - 1e-6 <= s <= cfg.texture_scale_range[1] + 1e-6 for s in scales)
    assert np.ptp(scales) > 0.2
    spec.compile()
    again = _randomized(3)[0]
    assert [again.assets[t.file] for t in again.textures if t.file] == [png for _, png in after.values()]


def test_switched_off_nothing_changes():
    spec, before, repeats, _ = _randomized(3, enabled=False)
    assert {t.name: (t.file, spec.assets[t.file]) for t in spec.textures if t.file} == before
    assert all(np.array_equal(np.array(m.texrepeat, float), repeats[m.name]) for m in spec.materials)
