"""A graceful stop on SIGINT (Ctrl-C) and SIGTERM (a scheduler preempting the run).

A signal is only recorded; the run raises ``Stopped`` at the next safe point
(``check``: between iterations, between the steps of starting a run). A training
iteration is finished first: the signal makes its checkpoint due
(``League.checkpoint_due``), so the run stops with nothing to redo and ``--resume`` goes
on from there; a second signal during the iteration's sampling and learning stops it at
once (``interruptible(signals=2)``), losing that iteration. Inside an ``interruptible()``
block (the final evaluation: nothing is written while its games are played) the first
signal raises at once. Raising anywhere else could land inside Ray's or torch's start-up
code, which may swallow it or leave half-built objects behind. Whatever was interrupted,
the last committed iteration and its checkpoint stay as they were: the run directory is
written only by whole steps.
"""

from __future__ import annotations

import signal
from contextlib import contextmanager
from typing import Iterator

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Stopped(KeyboardInterrupt):
    """A stop signal arrived; a ``KeyboardInterrupt`` so that libraries treat it like Ctrl-C."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return 128 + self.signum  # the shell's convention: 130 for SIGINT, 143 for SIGTERM


class StopRequests:
    """Owns the process's SIGINT and SIGTERM handlers while a run trains."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.count = 0  # signals received
        self._raise_at: int | None = None  # inside ``interruptible``: the count of signals that raises at once
        self._previous = {signum: signal.getsignal(signum) for signum in SIGNALS}

    def install(self) -> None:
        """Take over both signals (again after ``ray.init``, which installs its own SIGTERM handler)."""
        for signum in SIGNALS:
            signal.signal(signum, self._handle)

    @staticmethod
    def ignore() -> None:
        """From now on ignore both (a second Ctrl-C must not break the shutdown)."""
        for signum in SIGNALS:
            signal.signal(signum, signal.SIG_IGN)

    def restore(self) -> None:
        """Give both signals back to the handlers they had before (``main`` may run inside a test)."""
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)

    @property
    def requested(self) -> bool:
        return self.signum is not None

    def _handle(self, signum: int, frame: object) -> None:
        if self.signum is None:
            self.signum = signum
        self.count += 1
        if self._raise_at is not None and self.count >= self._raise_at:
            self._raise_at = None
            raise Stopped(self.signum)

    @staticmethod
    @contextmanager
    def held_by_main_thread() -> Iterator[None]:
        """Block SIGINT in the calling (main) thread while a library starts threads: they
        inherit the mask, so a Ctrl-C can never land in a thread of Ray's core worker
        (which swallowed it and later hung ``ray.shutdown``). A SIGINT that arrives
        meanwhile waits and is handled when the block ends. (Not SIGTERM: Ray's child
        processes inherit the mask too, and are stopped with SIGTERM.)"""
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})

    def check(self) -> None:
        if self.signum is not None:
            raise Stopped(self.signum)

    @contextmanager
    def interruptible(self, signals: int = 1) -> Iterator[None]:
        """A block that the ``signals``-th signal (counted since the run started) stops at once;
        ``signals=1``: the block starts only if no stop was asked for."""
        if signals == 1:
            self.check()
        self._raise_at = max(signals, self.count + 1)
        try:
            yield
        finally:
            self._raise_at = None
