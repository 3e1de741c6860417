"""What counts as a step in humanoid-footsteps: the touchdown rule and single-support air time.

Both read the feet's contact sensor once per policy step (``sensors.contact``: its air timer
advances by the policy step ``dt_s`` and counts the step of the landing, so a foot that was on
the ground at the end of step k and lands at the end of step m has ``last_air_time_s`` (m - k) dt).

A gait with a flight phase (both feet in the air) lands the stance foot a step or two after the
swing foot advanced the plan; that foot took off before the advance, aiming at nothing the plan
now asks, and must not count as the next swing foot's touchdown (issue 30 item 4). Nor should
the air-time reward pay for the flight itself: it counts a foot's time in the air only while
the other foot stands. The env (its touchdowns, rewards and ``touchdowns_per_s``), the placement
benchmark and the figure script all take touchdowns from ``swing_touchdown`` through
``HumanoidFootstepsEnv.touchdown``.
"""

from __future__ import annotations

import torch


def swing_touchdown(first_contact: torch.Tensor, last_air_time_s: torch.Tensor, since_advance_s: torch.Tensor,
                    min_air_time_s: float, dt_s: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Whether the swing foot's landing in the last policy step is a touchdown.

    Inputs (N,) for the swing foot: ``first_contact`` (bool, it landed in the last step),
    ``last_air_time_s`` (that flight's length, s), ``since_advance_s`` (s since the plan last
    advanced or started, counting the last step); ``dt_s`` the policy step, s.
    Returns (touchdown, flight_landing), both (N,) bool: a touchdown lands after at least
    ``min_air_time_s`` in the air from a take-off after the plan's last advance (its flight is
    no longer than the time since: half a step of slack for the timers' rounding); a flight
    landing is a landing long enough but from a take-off before the advance (not scored)."""
    landed = first_contact & (last_air_time_s >= min_air_time_s)
    took_off_after_advance = last_air_time_s <= since_advance_s + 0.5 * dt_s
    return landed & took_off_after_advance, landed & ~took_off_after_advance


def support_air_time(air_s: torch.Tensor, in_contact: torch.Tensor, first_contact: torch.Tensor,
                     dt_s: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Advance each foot's single-support air timer by one policy step.

    ``air_s`` (N, 2): per foot (left, right), its time in the air so far counted only while the
    other foot was on the ground, s; ``in_contact``, ``first_contact`` (N, 2) bool: the contact
    sensor's frame of this step. Like the sensor's air timer, the step a foot lands in counts.
    Returns (air_s, landed_s), both (N, 2) s: the timers after this step (0 on the ground) and,
    for a foot that landed in it, the flight's single-support time (0 elsewhere)."""
    in_air_this_step = first_contact | ~in_contact
    other_down = in_contact.flip(-1)
    air_s = air_s + dt_s * (in_air_this_step & other_down)
    landed_s = torch.where(first_contact, air_s, torch.zeros_like(air_s))
    return torch.where(in_contact, torch.zeros_like(air_s), air_s), landed_s


__all__ = ["support_air_time", "swing_touchdown"]
