"""Results of a batch of trials, and their storage in map files (ACRONYM style)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graspsim.sim.outcomes import TrialOutcome

__all__ = ["TrialResults", "RESULT_GROUPS"]

# where each protocol's results go in a map file (lift_place is the paper's test)
RESULT_GROUPS = {"lift_place": "grasps/qualities/mujoco", "tug": "grasps/qualities/mujoco_tug"}


@dataclass(frozen=True, eq=False)
class TrialResults:
    """Outcomes and metrics of N trials, in the order the poses were given.

    outcome: (N,) int8 :class:`TrialOutcome` codes; object_in_gripper: (N,) int8 0/1
    (ACRONYM's label: held after the hold / the tugs); metrics: name -> (N,) float
    (NaN where not simulated): object motion in the wrist frame per phase (``*_lin`` [m],
    ``*_ang`` [rad]), ``lift_height`` [m], ``place_error`` [m], ``place_tilt`` [rad],
    pad forces [N]. start_penetration: (N,) [m]; T_world_wrist: (N, 4, 4) as executed
    (noise included). protocol / scene / noise: parameter records; wall_time [s];
    simulated_seconds: simulated time summed over trials [s].
    """

    outcome: np.ndarray
    metrics: dict
    object_in_gripper: np.ndarray
    start_penetration: np.ndarray
    T_world_wrist: np.ndarray
    protocol: dict
    scene: dict
    seed: int
    noise: dict | None
    threads: int
    wall_time: float
    simulated_seconds: float
    extra: dict = field(default_factory=dict)
    #: (N,) what each START_COLLISION hit (:func:`~graspsim.sim.outcomes.collision_kind`):
    #: "table" (the table or the arm's keep-out box below it, not the object) or "object"
    #: (the object, the table maybe too); "" for the other trials. None: not recorded.
    start_kind: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.outcome)

    @property
    def outcomes(self) -> list[TrialOutcome]:
        return [TrialOutcome(int(o)) for o in self.outcome]

    def counts(self) -> dict[str, int]:
        """Number of trials per outcome label (all labels present, zeros included)."""
        return {o.label: int(np.sum(self.outcome == o)) for o in TrialOutcome}

    def start_collisions(self) -> dict[str, int]:
        """START_COLLISION trials by what they hit: {"object": n, "table": n} (all counted
        as "object" when not recorded)."""
        n = int(np.sum(self.outcome == TrialOutcome.START_COLLISION))
        if self.start_kind is None:
            return {"object": n, "table": 0}
        table = int(np.sum(self.start_kind == "table"))
        return {"object": n - table, "table": table}

    @property
    def feasible(self) -> int:
        """Trials whose start pose did not collide (the denominator of success_rate)."""
        return int(np.sum(self.outcome != TrialOutcome.START_COLLISION))

    @property
    def success_rate(self) -> float:
        """SUCCESS / feasible trials (START_COLLISION is reported apart); NaN if none."""
        f = self.feasible
        return float(np.sum(self.outcome == TrialOutcome.SUCCESS) / f) if f else float("nan")

    @property
    def trials_per_second(self) -> float:
        return len(self) / self.wall_time if self.wall_time > 0 else float("nan")

    def info(self) -> dict:
        """JSON record of how the results were made (stored with them)."""
        import mujoco

        return {"protocol": self.protocol, "scene": self.scene, "seed": self.seed,
                "noise": self.noise, "threads": self.threads,
                "mujoco_version": mujoco.__version__,
                "outcome_codes": {o.label: int(o) for o in TrialOutcome},
                "start_collisions": self.start_collisions(), **self.extra}

    def arrays(self) -> dict[str, np.ndarray]:
        """Per-grasp datasets: object_in_gripper, outcome, start_penetration, metrics."""
        out = {"object_in_gripper": self.object_in_gripper, "outcome": self.outcome,
               "start_penetration": self.start_penetration}
        out.update(self.metrics)
        return out
