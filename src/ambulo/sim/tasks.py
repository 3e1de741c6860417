"""Isaac's tasks: ``BaseTask`` and the World's task registry (``world.add_task`` and friends).

Why: Isaac samples (pick-and-place, follow-target, the hello-world tutorials) put the scene,
observations, metrics and per-step logic in a ``BaseTask`` and let the World drive it. The
World calls, as Isaac's does: ``task.set_up_scene(world.scene)`` at the first ``reset()``
(before the stage compiles, so the task may add objects), ``task.cleanup()`` before and
``task.post_reset()`` after every reset, and ``task.pre_step(time_step_index, simulation_time)``
at the start of every ``world.step()`` once the scenes are built. ``world.get_observations()``,
``calculate_metrics()`` and ``is_done()`` gather the tasks' answers.
"""

from __future__ import annotations

import numpy as np

from .current import current_world_or_none


class BaseTask:
    """Isaac's ``BaseTask(name, offset=None)``: subclass it and override what the task needs.

    ``offset`` (3,) stage units shifts the objects a subclass registers in ``self._task_objects``
    when it calls ``self._move_task_objects_to_their_frame()`` at the end of ``set_up_scene``.
    """

    def __init__(self, name: str, offset=None):
        if not isinstance(name, str) or not name:
            raise ValueError(f"task name {name!r} must be a non-empty string, unique in the World")
        self._name = name
        self._scene = None
        self._offset = np.zeros(3) if offset is None else np.asarray(offset, dtype=float).reshape(3)
        self._task_objects: dict = {}
        world = current_world_or_none()
        self._device = None if world is None else world.device

    @property
    def name(self) -> str:
        return self._name

    @property
    def scene(self):
        """The World's scene, once ``set_up_scene`` ran (None before)."""
        return self._scene

    @property
    def device(self):
        return self._device

    # -- what the World calls ----------------------------------------------------------
    def set_up_scene(self, scene) -> None:
        """Add the task's assets to ``scene``; subclasses call ``super().set_up_scene(scene)`` first."""
        self._scene = scene

    def pre_step(self, time_step_index: int, simulation_time: float) -> None:
        """Before each ``world.step()``: physics steps so far and simulated time (s)."""

    def post_reset(self) -> None:
        """After each ``world.reset()`` restored the objects' default states."""

    def cleanup(self) -> None:
        """Before each ``world.reset()``: remove temporary objects added during the episode."""

    # -- what the task reports (subclasses implement) ---------------------------------
    def get_observations(self) -> dict:
        raise NotImplementedError(f"{type(self).__name__}.get_observations: override it to return a dict")

    def calculate_metrics(self) -> dict:
        raise NotImplementedError(f"{type(self).__name__}.calculate_metrics: override it to return a dict")

    def is_done(self) -> bool:
        raise NotImplementedError(f"{type(self).__name__}.is_done: override it to return a bool")

    def get_params(self) -> dict:
        raise NotImplementedError(f"{type(self).__name__}.get_params: override it to return "
                                  "{name: {'value': v, 'modifiable': bool}}")

    def set_params(self, *args, **kwargs) -> None:
        raise NotImplementedError(f"{type(self).__name__}.set_params: override it to change the modifiable params")

    def get_description(self) -> str:
        return ""

    def get_task_objects(self) -> dict:
        return self._task_objects

    def _move_task_objects_to_their_frame(self) -> None:
        """Shift every registered task object by ``offset`` (and make that its default pose).

        Before the first reset (inside ``set_up_scene``) the objects are not simulated yet, so
        the offset moves their place on the stage; afterwards it moves them as Isaac does."""
        if not np.any(self._offset):
            return
        for task_object in self._task_objects.values():
            if task_object.is_valid():
                position, orientation = task_object.get_world_pose()
                task_object.set_world_pose(position=position + self._offset, orientation=orientation)
                task_object.set_default_state(position=position + self._offset, orientation=orientation)
            else:
                _shift_on_stage(task_object.prim_path, self._offset)


def _shift_on_stage(prim_path: str, offset: np.ndarray) -> None:
    """Move a not-yet-simulated prim's stage pose by ``offset`` (stage units)."""
    from ..core.paths import resolve_spec_prim
    from .current import current_world

    world = current_world("moving task objects")
    target = resolve_spec_prim(world.stage, prim_path)
    target.pos = [p + o * world.stage_units_in_meters for p, o in zip(target.pos, offset)]


class TaskHost:
    """The World's task registry (mixed into ``World``): Isaac's task members of ``World``."""

    @property
    def _current_tasks(self) -> dict[str, BaseTask]:
        return self.__dict__.setdefault("_tasks_by_name", {})

    def add_task(self, task: BaseTask) -> None:
        """Register ``task``; its ``set_up_scene`` runs at the next first ``reset()``."""
        if task.name in self._current_tasks:
            raise ValueError(f"the World already has a task named {task.name!r}; give each task a unique name")
        self._current_tasks[task.name] = task

    def get_task(self, name: str) -> BaseTask:
        if name not in self._current_tasks:
            raise KeyError(f"no task named {name!r}; have {sorted(self._current_tasks)} (world.add_task adds one)")
        return self._current_tasks[name]

    def get_current_tasks(self) -> dict[str, BaseTask]:
        """The registered tasks by name (Isaac returns this dict too)."""
        return self._current_tasks

    def is_tasks_scene_built(self) -> bool:
        return self.__dict__.get("_task_scene_built", False)

    def get_observations(self, task_name: str | None = None) -> dict:
        """One task's observations, or every task's merged into one dict (later tasks win)."""
        return self._from_tasks("get_observations", task_name)

    def calculate_metrics(self, task_name: str | None = None) -> dict:
        return self._from_tasks("calculate_metrics", task_name)

    def _from_tasks(self, method: str, task_name: str | None) -> dict:
        """``task.<method>()`` of one task, or of every task merged (later tasks win)."""
        tasks = [self.get_task(task_name)] if task_name is not None else self._current_tasks.values()
        merged: dict = {}
        for task in tasks:
            merged.update(getattr(task, method)())
        return merged

    def is_done(self, task_name: str | None = None) -> bool:
        """Whether the task (or every task; True with none) is done."""
        if task_name is not None:
            return bool(self.get_task(task_name).is_done())
        return all(task.is_done() for task in self._current_tasks.values())

    async def reset_async_set_up_scene(self, soft: bool = False) -> None:
        for task in self._current_tasks.values():
            task.set_up_scene(self.scene)

    async def reset_async_no_set_up_scene(self, soft: bool = False) -> None:
        built = self.is_tasks_scene_built()
        self.__dict__["_task_scene_built"] = True  # reset() below must not set the scenes up
        try:
            self.reset()
        finally:
            self.__dict__["_task_scene_built"] = built

    # -- hooks World.reset/step call -----------------------------------------------------
    def _tasks_before_reset(self) -> None:
        if not self.is_tasks_scene_built():
            for task in self._current_tasks.values():
                task.set_up_scene(self.scene)
            self.__dict__["_task_scene_built"] = True
        for task in self._current_tasks.values():
            task.cleanup()

    def _tasks_after_reset(self) -> None:
        for task in self._current_tasks.values():
            task.post_reset()

    def _tasks_pre_step(self) -> None:
        if self.is_tasks_scene_built():
            for task in self._current_tasks.values():
                task.pre_step(self.current_time_step_index, self.current_time)


__all__ = ["BaseTask", "TaskHost"]
