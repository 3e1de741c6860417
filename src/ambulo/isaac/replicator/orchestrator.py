"""``rep.orchestrator``: render the graph's frames, synchronously, and hand them to the writers.

In Kit, ``run()`` starts the graph and returns while frames are produced in the background;
here ``run()`` renders them all before it returns (there is no app loop to wait on), so
``wait_until_complete()`` finds nothing left to do. ``step()`` renders one frame, as Isaac's
standalone workflows call it in their own loop. The first frame builds the scene once
(``scene.py``) and a ``FrameProducer``; frame ``i`` depends only on (graph, seed, i).

``preview()`` does what Kit's does: it renders one frame of the graph (the next one, its nodes
evaluated) and hands it to no writer. In Kit the user then presses Run; ``ambulo run`` has no
UI, so a script that ends after ``preview()`` without any ``run``/``step`` gets what Run would
do: its triggers' frames rendered and written (``finish_script``, called by the runner), with a
line on stderr that says so. Replicator's "Hello World" writes its ``_output/`` that way.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from ambulo.replicator import FrameProducer

from .errors import Namespace, unsupported
from .graph import Graph, current_graph
from .scene import dataset_config


@dataclass
class RenderProduct:
    """``rep.create.render_product(camera, (width, height))``."""

    camera: str
    width: int
    height: int

    @property
    def path(self) -> str:
        return f"/Render/RenderProduct_{self.camera.rsplit('/', 1)[-1]}"

    @property
    def resolution(self) -> tuple[int, int]:
        return self.width, self.height


class Session:
    """The scene built from the graph, its frame producer and the writers of one run."""

    def __init__(self, graph: Graph):
        if len(graph.render_products) != 1:
            raise unsupported(f"orchestrator with {len(graph.render_products)} render products",
                              "create one rep.create.render_product per run")
        self.product = graph.render_products[0]
        self.writers = [w for w in graph.writers if self.product in w.render_products]
        self.annotators = [a for a in graph.annotators if self.product in a.render_products]
        for annotator in self.annotators:
            annotator.reset()
        needs = ["rgb"] + [a for w in self.writers for a in w.annotators] + [n for a in self.annotators for n in a.needs]
        self.camera_annotators = tuple(dict.fromkeys(needs))
        """What every frame renders: the writers' and the attached annotators' needs."""
        # BasicWriter's segmentation tells unlabelled geoms from the background by their geom ids
        self.producer = FrameProducer(dataset_config(graph, self.product, self.camera_annotators), geom_ids=True)
        self.camera = graph.prim(self.product.camera).extra
        self.seed = graph.seed

    def render(self, indices: list[int], write: bool = True) -> None:
        """Render frames ``indices``; hand them to the writers and annotators if ``write``."""
        table, model = self.producer.table, self.producer.model
        for _index, _log, capture in self.producer.frames(self.seed, indices):
            if not write:
                continue
            for writer in self.writers:
                writer.write(capture, table, self.camera, model)
            for annotator in self.annotators:
                annotator.update(capture, table, model, self.camera)

    def close(self) -> None:
        self.producer.close()


def _session(graph: Graph) -> Session:
    if graph.session is None:
        graph.session = Session(graph)
    return graph.session


def _frames_to_run(graph: Graph, num_frames: int | None) -> int:
    if num_frames is not None:
        return int(num_frames)
    counts = [t.num_frames for t in graph.triggers if t.num_frames is not None]
    if not counts:
        raise ValueError("rep.orchestrator.run() would run forever: give the trigger num_frames "
                         "(rep.trigger.on_frame(num_frames=N)) or call rep.orchestrator.run(num_frames=N)")
    return max(counts)


def run(num_frames: int | None = None, start_timeline: bool = False) -> None:
    """Render the trigger's ``num_frames`` frames (or ``num_frames``) after those already rendered."""
    graph = current_graph()
    count = _frames_to_run(graph, num_frames)
    session = _session(graph)
    graph.ran = True
    start = graph.frames_done
    session.render(list(range(start, start + count)))
    graph.frames_done = start + count


def run_until_complete(num_frames: int | None = None, start_timeline: bool = False) -> None:
    """Same as ``run``: frames are rendered before it returns."""
    run(num_frames, start_timeline)


def step(rt_subframes: int = -1, pause_timeline: bool = True, delta_time: float | None = None,
         wait_for_render: bool = True) -> None:
    """Render one frame: the triggers' nodes run, then the writers write it."""
    graph = current_graph()
    session = _session(graph)
    graph.ran = True
    session.render([graph.frames_done])
    graph.frames_done += 1


def preview() -> None:
    """Render the next frame of the graph and write nothing (Kit's preview); ``finish_script``
    runs the frames at the end of a script that never called ``run``/``step``."""
    graph = current_graph()
    graph.previewed = True
    _session(graph).render([graph.frames_done], write=False)


def finish_script() -> None:
    """What Kit's Run button does after a script that only previewed: run the triggers' frames
    with the writers. Called when an ``ambulo run`` script ends; nothing for other scripts."""
    graph = current_graph()
    if not graph.previewed or graph.frames_done or graph.ran:
        return
    counts = [t.num_frames for t in graph.triggers if t.num_frames is not None]
    if not counts:
        print("ambulo run: the script ended after rep.orchestrator.preview(); Run would render until stopped, "
              "so nothing is written: give rep.trigger.on_frame(num_frames=N) to write N frames", file=sys.stderr)
        return
    print(f"ambulo run: the script ended after rep.orchestrator.preview(); running its {max(counts)} frames "
          "with the writers, as Kit's Run button would", file=sys.stderr)
    run()


def wait_until_complete() -> None:
    """Nothing to wait for: ``run`` and ``step`` return after their frames are written."""


def stop() -> None:
    """End the run: release the renderer; a later ``step``/``run`` builds the scene again."""
    graph = current_graph()
    if graph.session is not None:
        graph.session.close()
        graph.session = None


def set_capture_on_play(value: bool) -> None:
    """ambulo captures only on ``run``/``step``, never on timeline play: False is what it does."""
    if value:
        raise unsupported("orchestrator.set_capture_on_play(True)",
                          "frames are captured by rep.orchestrator.run() or step()")


orchestrator = Namespace("orchestrator", {
    "run": run, "run_until_complete": run_until_complete, "step": step, "wait_until_complete": wait_until_complete,
    "stop": stop, "set_capture_on_play": set_capture_on_play, "preview": preview,
}, {
    "run_async": "use rep.orchestrator.run() (synchronous in ambulo)",
    "step_async": "use rep.orchestrator.step() (synchronous in ambulo)",
})
