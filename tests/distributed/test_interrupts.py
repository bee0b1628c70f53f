"""SIGINT and SIGTERM ask the run to stop; a second signal gives up at once."""

from __future__ import annotations

import os
import signal

import pytest

from genr8_dist.distributed.coordinator import StopRequest
from genr8_dist.distributed.interrupts import stop_on_signals


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_first_signal_sets_the_stop_request(sig):
    stop, said = StopRequest(), []
    before = signal.getsignal(sig)
    with stop_on_signals(stop, announce=said.append):
        os.kill(os.getpid(), sig)
        assert stop.reason == sig.name
    assert said and sig.name in said[0]
    assert signal.getsignal(sig) is before       # handlers restored


def test_second_signal_raises_keyboard_interrupt():
    stop = StopRequest()
    with pytest.raises(KeyboardInterrupt), stop_on_signals(stop):
        os.kill(os.getpid(), signal.SIGTERM)
        os.kill(os.getpid(), signal.SIGINT)
    assert stop.reason == "SIGTERM"


def test_a_command_leaves_the_signals_ignored_once_its_run_returns():
    """``genr8 run`` exits once its run returns: a signal during the rest of Ray's shutdown or the
    interpreter's exit must not kill it (exit -15 after "run complete"), so the handlers left behind
    ignore SIGINT and SIGTERM (``then``)."""
    stop = StopRequest()
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with stop_on_signals(stop, then=signal.SIG_IGN):
            pass
        assert all(signal.getsignal(sig) == signal.SIG_IGN for sig in before)
        os.kill(os.getpid(), signal.SIGTERM)    # ignored: this process lives on
        assert not stop
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
