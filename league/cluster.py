"""Joining a running Ray cluster (``--address``): the address checked first, token auth handled.

``ray.init(address=...)`` with nothing at the address retries for minutes, printing Ray's
C++ warnings, with Ctrl-C held back; and since Ray 2.60 a cluster may ask for a token
(``RAY_AUTH_MODE=token``: ``ray start --head`` turns it on by itself once
``~/.ray/auth_token`` exists, as any earlier local ``ray.init`` writes it), which a driver
sends only in token mode, and Ray turns that mode on by itself only for ``address="auto"``.
``check_cluster`` asks the cluster's GCS first, within ``CONNECT_TIMEOUT_S``, in Python
where a stop signal is heard, and either returns the address to give ``ray.init`` or raises
``ClusterError`` with one line saying what is wrong and what to set.

When the cluster asks for a token that this process was not told to send
(``RAY_AUTH_MODE`` unset) and this machine has one (``RAY_AUTH_TOKEN``,
``RAY_AUTH_TOKEN_PATH`` or ``~/.ray/auth_token``), token mode is turned on in this process,
as Ray does for ``auto``, and the cluster asked again.

Once joined, ``quiet_node_deaths`` shortens what Ray prints when a node dies. Ray's public API
has no way to do these: the reaches into Ray core's internals are in ``league/rllib/compat.py``.
"""

from __future__ import annotations

import os
import signal
import socket
import threading
from contextlib import contextmanager
from typing import Callable, ContextManager, Iterator

from league.rllib import compat

CONNECT_TIMEOUT_S = 20.0  # how long the cluster's GCS may take to answer, all asks together
AUTH_MODE = "RAY_AUTH_MODE"
TOKEN_WHERE = "~/.ray/auth_token, RAY_AUTH_TOKEN_PATH or RAY_AUTH_TOKEN (`ray get-auth-token` on the head prints it)"


class ClusterError(Exception):
    """The cluster at ``--address`` cannot be joined; the message says why and what to do."""


def gcs_address(address: str) -> str:
    """``host:port`` of the cluster's GCS, ``auto`` resolved as Ray resolves it."""
    try:
        return compat.gcs_address(address)
    except (ConnectionError, ValueError) as err:
        raise ClusterError(f"--address {address}: {err}") from None


def ask_gcs(address: str, timeout: float, interruptible: Callable[[], ContextManager]) -> BaseException | None:
    """Ask the GCS at ``address`` for its cluster id: ``None`` if it answered, else the error.

    Ray's client blocks in C++ and retries; it runs in a thread of its own with SIGINT
    blocked (its C++ threads inherit that), while this thread waits ``timeout`` at most
    inside ``interruptible()``, where a stop signal raises at once."""
    outcome: list[BaseException | None] = []

    def ask() -> None:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            compat.ask_gcs(address)
            outcome.append(None)
        except Exception as err:  # Ray's AuthenticationError, RpcError (timed out), ...
            outcome.append(err)

    thread = threading.Thread(target=ask, name="ask-gcs", daemon=True)  # daemon: left blocked on a time-out
    with quiet_stderr(), interruptible():
        thread.start()
        thread.join(timeout)
    return outcome[0] if outcome else TimeoutError(f"no answer within {timeout:.0f} s")


@contextmanager
def quiet_stderr() -> Iterator[None]:
    """File descriptor 2 to /dev/null meanwhile: Ray's C++ client writes a warning there at
    each failed try, and the caller says what failed in one line."""
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def check_cluster(address: str, interruptible: Callable[[], ContextManager]) -> str:
    """The address of the Ray cluster ``--address`` names, once its GCS answered this process
    (token mode turned on where the cluster asks for a token and this machine has one); or
    ``ClusterError`` within ``CONNECT_TIMEOUT_S`` or so. ``interruptible``: the block in which
    a stop signal raises at once (``StopRequests.interruptible``)."""
    from ray.exceptions import AuthenticationError

    target = gcs_address(address)
    host, _, port = target.rpartition(":")
    try:  # nothing listening is known at once: Ray's own client would retry it for minutes
        with interruptible():
            socket.create_connection((host.strip("[]"), int(port)), timeout=CONNECT_TIMEOUT_S / 2).close()
    except OSError as err:
        raise ClusterError(f"no Ray cluster at --address {address} ({target}): {err.strerror or err}") from None
    answer = ask_gcs(target, CONNECT_TIMEOUT_S / 2, interruptible)
    if isinstance(answer, AuthenticationError):
        mode = os.environ.get(AUTH_MODE)
        if mode is not None and mode.lower() != "token":
            raise ClusterError(
                f"the Ray cluster at {target} asks for a token and {AUTH_MODE}={mode} here: "
                f"set {AUTH_MODE}=token and give the head's token in {TOKEN_WHERE}"
            )
        if not compat.has_auth_token():
            raise ClusterError(f"the Ray cluster at {target} asks for a token and this machine has none: put the head's token in {TOKEN_WHERE}")
        if mode is None:
            compat.enable_token_auth()
            answer = ask_gcs(target, CONNECT_TIMEOUT_S / 2, interruptible)
        if isinstance(answer, AuthenticationError):
            raise ClusterError(
                f"the Ray cluster at {target} refused this machine's token: set RAY_AUTH_TOKEN (or RAY_AUTH_TOKEN_PATH) "
                "to the head's token (`ray get-auth-token` on the head prints it)"
            )
    if answer is not None:
        raise ClusterError(f"the Ray cluster at --address {address} ({target}) did not answer: {str(answer).splitlines()[0]}")
    return target


def node_death_lines(lines: list[str]) -> list[str]:
    """What to print of the lines Ray's error channel sends a driver from a raylet: a dead
    raylet's message (its last 20-odd log lines) dropped, and of the node's death (several lines
    on what may have caused it) the first sentence; any other message as it is."""
    kept = []
    for line in lines:
        if "Raylet is terminated" in line:
            continue  # the same death as the "marked dead" message
        if "has been marked dead" in line:
            line = line.split("\n")[0].split(". ")[0].rstrip(".") + "."
        kept.append(line)
    return kept


def quiet_node_deaths() -> None:
    """Node deaths in a line each, in what Ray prints of its error channel (``node_death_lines``)."""
    compat.filter_driver_errors(node_death_lines)
