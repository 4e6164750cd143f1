"""Ctrl-C for a child process as a terminal delivers it.

A shell without job control (a script's ``cmd &``, ``nohup``, some CI runners) starts background
commands with SIGINT ignored, and a child inherits an ignored signal across ``exec``. Python then
installs no KeyboardInterrupt handler, so a test that sends SIGINT to a command it started
measures nothing but that inheritance ("did not stop within 120 s of Ctrl-C", or a sweep that
ran to its end). Pass :func:`as_typed` as ``preexec_fn`` to every ``Popen`` that will be sent a
Ctrl-C: the child starts with SIGINT at its default, as a command typed at a terminal does.
"""

import signal

__all__ = ["as_typed"]


def as_typed() -> None:
    """``preexec_fn``: SIGINT back to its default in the child before it runs."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
