"""Progress of the long commands (render, dataset, scenes).

On a terminal: one rich progress bar (:func:`progress_bar`): description, bar, done/total, elapsed
time and the last finished item (a task's ``last`` field). Rich is imported on use, so ``--help``
stays cheap.

Anywhere else (a log file, CI, a Ray driver's output, ``illumix render … 2> log``): plain lines
(:class:`ProgressLines`), one per finished job with its time, the mean time per job and an ETA, and
a heartbeat line after every ``interval`` seconds without one (``still rendering mini/a/lamp: 40 s,
3/8 done, ETA 2 min``), so a log shows that a long render is alive and how far it got."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from illumix.renderer_jobs.cost_model import duration  # (no heavy imports)

__all__ = ["ProgressLines", "duration", "progress_bar", "stream_writer"]


def progress_bar(console, *, disable: bool = False, transient: bool = False):
    """A ``rich.progress.Progress`` on ``console`` (stderr); add tasks with a ``last=""`` field."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    return Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    TextColumn("{task.fields[last]}"), console=console, disable=disable, transient=transient)


class ProgressLines:
    """Plain progress lines for jobs run in plan order (module docstring), written by ``write``.

    ``jobs``: ``[(label, phase)]`` in the order the executor starts them (a phase starts once every
    job of the earlier phases has finished: the views, then the cubes). ``parallel``: how many run at
    once (the local pool's workers) — the heartbeat then names the running jobs and their times;
    ``None`` when unknown (Ray: the cluster decides). ``weights``: each label's expected cost (e.g. its
    estimated CPU seconds, :mod:`renderer_jobs.cost_model`); the ETA is the time so far scaled by the
    weight left over the weight done (equal weights without it). Thread-safe: the heartbeat runs in
    a daemon thread between :meth:`start` and :meth:`stop` (or a ``with`` block)."""

    def __init__(self, write: Callable[[str], None], jobs: list[tuple[str, int]], *, parallel: int | None = 1,
                 weights: dict[str, float] | None = None, interval: float = 10.0, verb: str = "rendering",
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.write, self.jobs, self.parallel, self.interval, self.verb = write, list(jobs), parallel, interval, verb
        self.clock = clock
        self.phase_of = dict(self.jobs)
        self.weights = {lbl: max(1e-9, float((weights or {}).get(lbl, 1.0))) for lbl, _ in self.jobs}
        self.total_weight = sum(self.weights.values()) or 1.0
        self.left_in_phase: dict[int, int] = {}
        for _, phase in self.jobs:
            self.left_in_phase[phase] = self.left_in_phase.get(phase, 0) + 1
        self.finished: set[str] = set()
        self.started: dict[str, float] = {}
        self.n_done = self.n_failed = 0
        self.done_weight = 0.0
        self.last_pass = ""
        self.t0 = self.last_line = self.t_last = clock()
        self._next = 0  # the first job of `jobs` perhaps not yet started
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._admit(self.t0)

    # -- the jobs' states -----------------------------------------------------------------------------
    def _admit(self, now: float) -> None:
        """Start (in our model) the next jobs in order while fewer than ``parallel`` run."""
        if self.parallel is None:
            return
        running = sum(1 for lbl in self.started if lbl not in self.finished)
        while running < self.parallel and self._next < len(self.jobs):
            label, phase = self.jobs[self._next]
            if label in self.finished or label in self.started:
                self._next += 1
                continue
            if any(n for ph, n in self.left_in_phase.items() if ph < phase):
                return  # the executor waits for the earlier phase
            self.started[label] = now
            self._next += 1
            running += 1

    def running(self) -> list[tuple[str, float]]:
        """``[(label, seconds running)]`` of the jobs our model says run now."""
        now = self.clock()
        return [(lbl, now - t) for lbl, t in self.started.items() if lbl not in self.finished]

    def eta(self, now: float | None = None) -> float | None:
        """Seconds left: the time so far × the weight left / the weight done (None before any is done)."""
        if not self.done_weight:
            return None
        now = self.clock() if now is None else now
        left = max(0.0, self.total_weight - self.done_weight)
        return (now - self.t0) * left / self.done_weight

    def _status(self, now: float) -> str:
        """``3/8 done, 12 s per job, ETA 1 min`` (failures and the rate only where known)."""
        n = len(self.jobs)
        parts = [f"{self.n_done + self.n_failed}/{n} done" + (f" ({self.n_failed} failed)" if self.n_failed else "")]
        if self.n_done:  # the mean wall time per finished job, jobs in parallel counted as such
            parts.append(f"{duration((self.t_last - self.t0) / (self.n_done + self.n_failed))} per job")
        eta = self.eta(now)
        if self.n_done + self.n_failed < n:
            parts.append(f"ETA {duration(eta)}" if eta is not None else "ETA after the first job")
        return ", ".join(parts)

    # -- events ---------------------------------------------------------------------------------------
    def job_done(self, label: str, seconds: float | None = None, note: str = "") -> None:
        """A job finished: ``[3/8] finished mini/a/lamp in 12 s (note); …``."""
        with self._lock:
            now = self.clock()
            took = seconds if seconds is not None else now - self.started.get(label, self.t0)
            self._finish(label, now, failed=False)
            extra = f" ({note})" if note else ""
            self._emit(f"[{self.n_done + self.n_failed}/{len(self.jobs)}] finished {label} in {duration(took)}"
                       f"{extra}; {self._status(now)}", now)

    def job_failed(self, label: str, message: str) -> None:
        """A job failed and the others go on: ``[4/8] failed mini/a/bulb: message; …``."""
        with self._lock:
            now = self.clock()
            self._finish(label, now, failed=True)
            self._emit(f"[{self.n_done + self.n_failed}/{len(self.jobs)}] failed {label}: {message}; "
                       f"{self._status(now)}", now)

    def pass_done(self, label: str) -> None:
        """A sub-step of the running job (the Cycles backend's passes): named by the next heartbeat."""
        with self._lock:
            self.last_pass = label

    def _finish(self, label: str, now: float, failed: bool) -> None:
        if label in self.finished:
            return
        self.finished.add(label)
        phase = self.phase_of.get(label)
        if phase is not None:
            self.left_in_phase[phase] -= 1
        if failed:
            self.n_failed += 1
        else:
            self.n_done += 1
        self.done_weight += self.weights.get(label, 1.0)
        self.t_last = now
        self.last_pass = ""
        self._admit(now)

    def heartbeat_line(self) -> str:
        """``still rendering mini/a/lamp: 40 s, 3/8 done, ETA 2 min`` (the running jobs, where known)."""
        now = self.clock()
        running = self.running()
        step = f" ({self.last_pass})" if self.last_pass else ""
        if len(running) == 1:
            (label, t), = running
            return f"still {self.verb} {label}{step}: {duration(t)}, {self._status(now)}"
        if running:
            names = ", ".join(f"{lbl} ({duration(t)})" for lbl, t in running[:3])
            more = f" and {len(running) - 3} more" if len(running) > 3 else ""
            return f"still {self.verb} {names}{more}{step}: {self._status(now)}"
        return f"still {self.verb}{step}: {duration(now - self.t0)} so far, {self._status(now)}"

    def heartbeat(self) -> bool:
        """Write the heartbeat line if no line was written for ``interval`` seconds; True if written."""
        with self._lock:
            now = self.clock()
            if now - self.last_line < self.interval or self.n_done + self.n_failed >= len(self.jobs):
                return False
            self._emit(self.heartbeat_line(), now)
            return True

    def _emit(self, line: str, now: float) -> None:
        self.last_line = now
        self.write(line)

    # -- the heartbeat thread -------------------------------------------------------------------------
    def start(self) -> ProgressLines:
        if self._thread is None and self.interval > 0:
            self._thread = threading.Thread(target=self._beat, name="illumix-heartbeat", daemon=True)
            self._thread.start()
        return self

    def _beat(self) -> None:
        while not self._stop.wait(min(1.0, self.interval / 4)):
            try:
                self.heartbeat()
            except Exception:  # a closed stream: progress is never worth a crash
                return

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    def __enter__(self) -> ProgressLines:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def stream_writer(console) -> Callable[[str], None]:
    """Write whole lines to ``console``'s file (stderr) unwrapped, flushed at once: a log gets each
    line when it happens, never cut at the console's width."""

    def write(line: str) -> None:
        try:
            f = console.file
            f.write(line + "\n")
            f.flush()
        except (OSError, ValueError):  # a closed pipe or file: the render goes on without its log
            pass

    return write
