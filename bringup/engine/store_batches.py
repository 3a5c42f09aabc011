"""Bundle-store commits of a local run: one SQLite transaction per satellite every N lockstep steps.

A satellite commits its bundle store once per lockstep step (sat_node/satellite.py, BundleStore.begin /
commit): that is the durability a ROS satellite process needs, because a killed process is restarted
and resumes from its store (bringup/engine/ros/launcher.py ``--restart``). The local engine runs every
participant in one process and has no resume: a kill ends the whole run. There per-step commits buy
nothing and cost ~54 us each, ~52k of them on the paper run (24 satellites x 2161 steps, py-spy: 13 %
of the run). :class:`StoreBatches` opens a batch on every store before the first step (the
satellite's own per-step ``begin()`` then joins it instead of opening one) and commits every
``every_steps`` steps and once at the end, before the stores close. Puts and deletes of one bundle
within a batch collapse into its last write (BundleStore), so fewer rows reach the file.

What stays true: the file is always a committed step boundary (a kill, or a run that fails, leaves
the state of the last commit, never half a step), and after :meth:`StoreBatches.finish` it holds exactly what per-step
commits would have left. How we know: tests/unit/test_store_batches.py compares the final rows with
per-step commits on a scripted run, checks the commit cadence, and checks that a batch open at
``close`` is committed, not lost.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["STORE_COMMIT_STEPS", "StoreBatches"]

# lockstep steps per commit in a local run (steps are at most lockstep_max_step_s apart: 10 s on the
# paper scenario, so a commit at least every ~8 simulated minutes)
STORE_COMMIT_STEPS = 50


class StoreBatches:
    """Batches for ``stores`` (sat_node.dtn.store.BundleStore); call :meth:`step` once per lockstep
    step (after :meth:`start`) and :meth:`finish` after the participants' ``finish`` and before the stores close."""

    def __init__(self, stores: Iterable, every_steps: int = STORE_COMMIT_STEPS):
        if every_steps < 1:
            raise ValueError(f"StoreBatches: every_steps must be >= 1, got {every_steps}")
        self.stores = list(stores)
        self.every_steps = int(every_steps)
        self.commits = 0
        self._since = 0
        self._open = False

    def start(self) -> None:
        for s in self.stores:
            if not s.begin():
                raise RuntimeError(f"{s.path}: a transaction is already open; cannot batch its commits")
        self._open = True

    def step(self) -> None:
        """A lockstep step begins: the batch commits once it holds ``every_steps`` whole steps."""
        self._since += 1
        if self._since > self.every_steps:
            self._commit()
            self.start()
            self._since = 1

    def finish(self) -> None:
        if self._open:
            self._commit()

    def abandon(self) -> None:
        """After a failed run: drop the open batch (it may hold half a step); each file stays at its
        last commit, at most ``every_steps`` steps before the failure (the run's bag has them all)."""
        if self._open:
            for s in self.stores:
                s.rollback()
            self._open = False

    def _commit(self) -> None:
        for s in self.stores:
            s.commit()
        self.commits += 1
        self._since = 0
        self._open = False
