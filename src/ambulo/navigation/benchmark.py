"""Navigation benchmarks: many ``metrics.run_episode`` episodes over a process pool, resumable, and
their summary. ``ambulo navigate --episodes N`` and ``benchmarks/navigate.py`` both run this.

    specs = [EpisodeSpec(apartment_seed=s, episode_seed=0, mode="oracle") for s in range(100)]
    run = run_benchmark(specs, "out/nav", workers=2)
    print(format_table(run.summary))

- **One episode per task.** Each finished episode's ``EpisodeResult`` is written as JSON (atomically,
  by the worker) to ``<out>/episodes/<spec.name>.json``. A later run with the same out folder skips
  the episodes whose JSON exists, so a killed run resumes where it stopped. An episode that raises
  writes nothing (a rerun retries it) and counts as a failure in the summary (``errors``).
- **Groups.** Specs are grouped by (mode, walker, randomized) and the groups run one after the
  other, so each group's wall-clock throughput (episodes per minute) is its own.
- **Workers**: one process per episode, one torch and one OpenCV thread each. Full mode's perception
  (the TSDF, the odometry's map and refinement) runs where ``with_perception_device`` puts it
  (``base``; default the CPU); the head camera renders where MuJoCo's GL backend does.
- **Ceiling** (``ceiling_every`` k > 0): every k-th episode of a group (the first, the k+1-th, ...) is
  followed, in the same worker, by ``ceiling.physics_policy_ceiling`` for the episode's simulated
  time: the same robot and scene stepped with physics and walker only. Its result is the episode
  JSON's ``ceiling``.
- **Summary** per group (``summarize``): success rate, SPL, fall rate, collisions per episode, stuck
  rate, 95th percentile of the replan wall times (all the group's replans pooled), simulated over
  wall time (sums over episodes), episodes per minute (only episodes run now, over the group's wall
  time; None when all were resumed); with ceilings, the ceiling's simulated over wall time and the
  episodes' over it (both sums over the episodes that have a ceiling; None without).
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import json
import os
import time
import traceback
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from ..utils.atomic import atomic_write_json, atomic_write_text
from ..utils.checks import InvalidValueError
from .metrics import EpisodeCfg, p95
from .navigator import MODES, NavigatorCfg
from .randomization import RandomizationCfg
from .world import NavWorldCfg

WALKERS = ("policy", "zmp", "footsteps")


@dataclass(frozen=True)
class EpisodeSpec:
    """One benchmark episode: ``apartment(apartment_seed)``, start and goal drawn with ``episode_seed``."""

    apartment_seed: int
    episode_seed: int = 0
    mode: str = "oracle"
    walker: str = "policy"
    randomize: bool = False

    @property
    def group(self) -> tuple[str, str, bool]:
        return self.mode, self.walker, self.randomize

    @property
    def name(self) -> str:
        """File stem of the episode's JSON, e.g. ``oracle-policy-nominal-apt0007-ep0``."""
        rand = "rand" if self.randomize else "nominal"
        return f"{self.mode}-{self.walker}-{rand}-apt{self.apartment_seed:04d}-ep{self.episode_seed}"


def group_label(group: tuple[str, str, bool]) -> str:
    mode, walker, randomize = group
    return f"{mode}/{walker}" + ("/rand" if randomize else "")


def zmp_walker_available() -> bool:
    """Whether the navigation package has its ZMP walker adapter (``navigation.zmp_walker``)."""
    return importlib.util.find_spec(f"{__package__}.zmp_walker") is not None


def make_walker(name: str):
    """The walker ``name`` (``WALKERS``): None for the navigator's default ``PolicyWalker``, the ZMP
    adapter for ``zmp``, the learned footstep walker (``footstep_walker.FootstepPolicyWalker``) for
    ``footsteps``; ``InvalidValueError`` when it is unknown or not available."""
    if name == "policy":
        return None
    if name == "footsteps":
        from .footstep_walker import FootstepPolicyWalker

        return FootstepPolicyWalker()
    if name != "zmp":
        raise InvalidValueError("walker", name, "unknown walker", f"use one of {', '.join(WALKERS)}")
    if not zmp_walker_available():
        raise InvalidValueError("walker", name, "the ZMP walker adapter (ambulo.navigation.zmp_walker) is not "
                                "available yet", "use the policy walker (--walker policy)")
    module = importlib.import_module(f"{__package__}.zmp_walker")
    cls = getattr(module, "ZmpWalker", None)
    if cls is None:
        raise InvalidValueError("walker", name, "navigation.zmp_walker has no ZmpWalker class",
                                "use the policy walker (--walker policy)")
    return cls()


def episode_cfg(spec: EpisodeSpec, base: EpisodeCfg | None = None) -> EpisodeCfg:
    """``base`` (default ``EpisodeCfg()``) with the spec's mode and randomization (seeded by the
    apartment and episode seeds, so a rerun draws the same pushes and noise)."""
    base = base or EpisodeCfg()
    world = NavWorldCfg(**{**base.world.__dict__, "seed": spec.apartment_seed * 1000 + spec.episode_seed,
                           "randomization": RandomizationCfg(**{**base.world.randomization.__dict__,
                                                                "enabled": spec.randomize})})
    navigator = NavigatorCfg(**{**base.navigator.__dict__, "mode": spec.mode})
    return EpisodeCfg(**{**base.__dict__, "navigator": navigator, "world": world})


def with_perception_device(device: str, base: EpisodeCfg | None = None) -> EpisodeCfg:
    """``base`` (default ``EpisodeCfg()``) with the full mode's perception on the torch ``device``: the
    TSDF (``OnlineMapperCfg.device``) and the odometry's map, rigidity check and refinement
    (``VoCfg.device``; ORB, its matching and PnP stay on the host). ``InvalidValueError`` for a CUDA
    device on a machine without one (before any worker starts)."""
    import torch

    if torch.device(device).type == "cuda" and not torch.cuda.is_available():
        raise InvalidValueError("perception_device", device, "CUDA is not available here", "pass cpu")
    base = base or EpisodeCfg()
    nav = base.navigator
    vo = dataclasses.replace(nav.vo, vo=dataclasses.replace(nav.vo.vo, device=device))
    navigator = dataclasses.replace(nav, vo=vo, mapper=dataclasses.replace(nav.mapper, device=device))
    return dataclasses.replace(base, navigator=navigator)


def check_spec(spec: EpisodeSpec) -> None:
    if spec.mode not in MODES:
        raise InvalidValueError("mode", spec.mode, "unknown mode", f"use one of {', '.join(MODES)}")
    if spec.walker not in WALKERS:
        raise InvalidValueError("walker", spec.walker, "unknown walker", f"use one of {', '.join(WALKERS)}")
    if spec.walker == "zmp":
        make_walker("zmp")  # fails early, before any pool starts


def run_spec(spec: EpisodeSpec, out_dir: str | None, base: EpisodeCfg | None = None, ceiling: bool = False) -> dict:
    """Run one episode (and then, with ``ceiling``, its physics-and-walker ceiling for the same
    simulated time); write its JSON under ``out_dir/episodes`` (if given); return the result as a
    dict (``{"spec": ..., "error": traceback}`` when the episode raised: nothing is written)."""
    from .ceiling import physics_policy_ceiling
    from .metrics import run_episode

    try:
        cfg = episode_cfg(spec, base)
        result = run_episode(spec.apartment_seed, spec.episode_seed, cfg, walker=make_walker(spec.walker))
        top = physics_policy_ceiling(spec.apartment_seed, spec.episode_seed, result.time_s, cfg,
                                     walker=make_walker(spec.walker)) if ceiling else None
    except Exception:  # one broken episode must not end a 100-episode run; it is reported
        return {"spec": asdict(spec), "error": traceback.format_exc()}
    data = {**asdict(result), "spec": asdict(spec)}
    if top is not None:
        data["ceiling"] = {"time_s": top.time_s, "wall_s": top.wall_s, "sim_to_wall": top.sim_to_wall,
                           "fell": top.fell}
    if out_dir is not None:
        atomic_write_json(episode_path(out_dir, spec), data, indent=1)
    return data


def _cv2():
    """OpenCV, or None without the perception extra (full mode's odometry uses it)."""
    try:
        import cv2
    except ImportError:
        return None
    return cv2


def pin_threads() -> None:
    """torch and OpenCV on one thread, as in every benchmark worker: one episode per core, and a
    single ``ambulo navigate`` episode sums in the same order as the benchmark's (a different thread
    count can change a float reduction, and with it an episode's decisions)."""
    import torch

    # threads would only fight over the cores (OpenCV's pool is as wide as the machine: 64 threads
    # per worker on a 64-core host running 62 workers)
    torch.set_num_threads(1)
    if (cv2 := _cv2()) is not None:
        cv2.setNumThreads(1)


@contextlib.contextmanager
def pinned_threads():
    """``pin_threads`` for a block, then the thread counts as they were (``ambulo navigate`` run
    in a process that goes on, e.g. a test session)."""
    from ..perception.torch_threads import one_torch_thread

    cv2 = _cv2()
    cv2_threads = cv2.getNumThreads() if cv2 is not None else None
    if cv2 is not None:
        cv2.setNumThreads(1)
    try:
        with one_torch_thread("cpu"):
            yield
    finally:
        if cv2 is not None:
            cv2.setNumThreads(cv2_threads)


def episode_path(out_dir: str | os.PathLike, spec: EpisodeSpec) -> Path:
    return Path(out_dir) / "episodes" / f"{spec.name}.json"


@dataclass
class BenchmarkRun:
    results: list[dict] = field(default_factory=list)
    """Every spec's result dict (read back from JSON for resumed episodes), in spec order."""
    resumed: int = 0
    """Episodes skipped because their JSON existed."""
    group_wall_s: dict = field(default_factory=dict)
    """Per group label: wall time spent running its episodes now, s."""
    group_run: dict = field(default_factory=dict)
    """Per group label: episodes run now (not resumed)."""
    summary: dict = field(default_factory=dict)


def run_benchmark(specs: Iterable[EpisodeSpec], out_dir: str | os.PathLike, *, workers: int = 1,
                  base: EpisodeCfg | None = None, log: Callable[[str], None] | None = print,
                  ceiling_every: int = 0) -> BenchmarkRun:
    """Run ``specs`` (module docstring): ``workers`` processes (1: in this process), results and
    ``summary.json`` under ``out_dir``; ``ceiling_every`` k > 0: every k-th episode of a group gets
    its ceiling (module docstring)."""
    specs = list(dict.fromkeys(specs))
    if workers < 1:
        raise InvalidValueError("workers", workers, "needs at least one worker", "pass workers >= 1")
    if ceiling_every < 0:
        raise InvalidValueError("ceiling_every", ceiling_every, "must be >= 0", "pass 0 (no ceiling) or k >= 1")
    with_ceiling = {spec for group in _by_group(specs).values() for i, spec in enumerate(group)
                    if ceiling_every and i % ceiling_every == 0}
    for spec in specs:
        check_spec(spec)
    out = Path(out_dir)
    (out / "episodes").mkdir(parents=True, exist_ok=True)
    run = BenchmarkRun()
    by_spec: dict[EpisodeSpec, dict] = {}
    todo: dict[tuple, list[EpisodeSpec]] = {}
    for spec in specs:
        path = episode_path(out, spec)
        if path.is_file():
            by_spec[spec] = json.loads(path.read_text())
            run.resumed += 1
        else:
            todo.setdefault(spec.group, []).append(spec)
    if log and run.resumed:
        log(f"resuming: {run.resumed} of {len(specs)} episodes already done in {out / 'episodes'}")
    pool = None
    if workers > 1 and sum(len(v) for v in todo.values()) > 1:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"), initializer=pin_threads)
    try:
        for group, group_specs in todo.items():
            t0 = time.perf_counter()
            if pool is None:
                done = ((spec, run_spec(spec, str(out), base, spec in with_ceiling)) for spec in group_specs)
            else:
                futures = {pool.submit(run_spec, spec, str(out), base, spec in with_ceiling): spec
                           for spec in group_specs}
                done = ((futures[f], f.result()) for f in as_completed(futures))
            for spec, data in done:
                by_spec[spec] = data
                if "error" in data:  # the whole traceback, beside the results (a rerun retries the episode)
                    atomic_write_text(error_path(out, spec), data["error"])
                if log:
                    log(_line(spec, data))
            label = group_label(group)
            run.group_wall_s[label] = time.perf_counter() - t0
            run.group_run[label] = len(group_specs)
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    run.results = [by_spec[s] for s in specs]
    run.summary = summarize(run.results, run.group_wall_s, run.group_run)
    atomic_write_text(out / "summary.json", json.dumps(run.summary, indent=1) + "\n")
    return run


def _by_group(specs: list[EpisodeSpec]) -> dict[tuple, list[EpisodeSpec]]:
    groups: dict[tuple, list[EpisodeSpec]] = {}
    for spec in specs:
        groups.setdefault(spec.group, []).append(spec)
    return groups


def error_path(out_dir: str | os.PathLike, spec: EpisodeSpec) -> Path:
    """Where the traceback of an episode that raised is written (not a result: it is run again)."""
    return Path(out_dir) / "episodes" / f"{spec.name}.error.txt"


def _line(spec: EpisodeSpec, data: dict) -> str:
    if "error" in data:
        return f"{spec.name}: ERROR {data['error'].strip().splitlines()[-1]}"
    return (f"{spec.name}: {data['status']}{' (success)' if data['success'] else ''}, SPL {data['spl']:.2f}, "
            f"{data['time_s']:.1f} s sim in {data['wall_s']:.1f} s wall, {data['collisions']} collisions")


def _group_of(data: dict) -> tuple[str, str, bool]:
    s = data["spec"]
    return s["mode"], s["walker"], bool(s["randomize"])


def summarize(results: list[dict], group_wall_s: dict | None = None, group_run: dict | None = None) -> dict:
    """Per group label (``group_label``): the module docstring's figures; errors count as failures."""
    groups: dict[tuple, list[dict]] = {}
    for data in results:
        groups.setdefault(_group_of(data), []).append(data)
    summary = {}
    for group, items in groups.items():
        ok = [d for d in items if "error" not in d]
        n = len(items)
        replans = [t for d in ok for t in d["replan_wall_s"]]
        label = group_label(group)
        wall = (group_wall_s or {}).get(label)
        ran = (group_run or {}).get(label, 0)
        sim_s, wall_s = sum(d["time_s"] for d in ok), sum(d["wall_s"] for d in ok)
        topped = [d for d in ok if d.get("ceiling")]
        top_sim, top_wall = sum(d["ceiling"]["time_s"] for d in topped), sum(d["ceiling"]["wall_s"] for d in topped)
        own = sum(d["time_s"] for d in topped) / max(sum(d["wall_s"] for d in topped), 1e-9)
        ceiling = top_sim / top_wall if top_wall > 0 else None
        summary[label] = {
            "episodes": n,
            "success": sum(d["success"] for d in ok) / n,
            "spl": sum(d["spl"] for d in ok) / n,
            "falls": sum(d["fell"] for d in ok) / n,
            "collisions_per_episode": sum(d["collisions"] for d in ok) / n,
            "stuck": sum(d["stuck"] for d in ok) / n,
            "replan_p95_ms": 1e3 * p95(replans),
            "sim_to_wall": sim_s / wall_s if wall_s > 0 else None,
            "ceiling_sim_to_wall": ceiling,
            "of_ceiling": own / ceiling if ceiling else None,
            "episodes_per_min": 60.0 * ran / wall if wall and ran else None,
            "statuses": {s: sum(d.get("status") == s for d in ok) for s in sorted({d["status"] for d in ok})},
            "errors": n - len(ok),
            "ate_m_median": float(np.median([d["ate_m"] for d in ok])) if ok else None,
        }
    return summary


_COLUMNS = (("episodes", "n", "{:d}"), ("success", "success", "{:.0%}"), ("spl", "SPL", "{:.2f}"),
            ("falls", "falls", "{:.0%}"), ("collisions_per_episode", "coll/ep", "{:.2f}"),
            ("stuck", "stuck", "{:.0%}"), ("replan_p95_ms", "p95 replan ms", "{:.0f}"),
            ("sim_to_wall", "sim/wall", "{:.2f}"), ("ceiling_sim_to_wall", "ceiling sim/wall", "{:.2f}"),
            ("of_ceiling", "of ceiling", "{:.0%}"), ("episodes_per_min", "ep/min", "{:.2f}"),
            ("errors", "errors", "{:d}"))


def format_table(summary: dict) -> str:
    """The summary as a Markdown table, one row per group."""
    head = "| group | " + " | ".join(title for _, title, _ in _COLUMNS) + " |"
    rows = [head, "|" + "---|" * (len(_COLUMNS) + 1)]
    for label, s in summary.items():
        cells = ["-" if s.get(key) is None else fmt.format(s[key]) for key, _, fmt in _COLUMNS]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


__all__ = ["WALKERS", "BenchmarkRun", "EpisodeSpec", "check_spec", "episode_cfg", "episode_path", "format_table",
           "group_label", "make_walker", "run_benchmark", "run_spec", "summarize", "with_perception_device",
           "zmp_walker_available"]
