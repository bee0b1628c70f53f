"""Interrupting a run: Ctrl-C (SIGINT) or a job stop (SIGTERM, what ``ray job stop`` sends).

The first signal asks the coordinator to stop: it commits every generation that is complete, records an
``interrupt`` event and returns, and the command exits 0 saying how to resume. A second signal gives
up at once (``KeyboardInterrupt``); the run store is still consistent because every commit is atomic,
and ``genr8 resume`` recomputes whatever was not committed.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType

from genr8_dist.distributed.coordinator import StopRequest

__all__ = ["SIGNALS", "stop_on_signals"]

SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def stop_on_signals(stop: StopRequest, announce: Callable[[str], object] | None = None, *,
                    then: Callable[[int, FrameType | None], object] | int | None = None
                    ) -> Iterator[StopRequest]:
    """While inside, SIGINT and SIGTERM set ``stop`` (the second one raises ``KeyboardInterrupt``).

    ``announce(text)`` is told when a stop is requested. On the way out the previous handlers come
    back, or ``then`` where given: a command that exits once its run returns leaves the signals
    ignored (``signal.SIG_IGN``), so one during the rest of Ray's shutdown or the interpreter's exit
    changes nothing (the run is complete, or stopped) instead of killing the process. Outside the
    main thread signals cannot be caught; the context then does nothing and ``stop`` can still be
    set by the caller.
    """
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        if stop:
            raise KeyboardInterrupt(f"second {name}")
        stop.set(name)
        if announce is not None:
            announce(f"{name} received: committing the complete generations, then stopping "
                     "(send it again to stop at once)")

    previous = {sig: signal.getsignal(sig) for sig in SIGNALS}
    for sig in SIGNALS:
        signal.signal(sig, handler)
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, then if then is not None else old if old is not None else signal.SIG_DFL)
