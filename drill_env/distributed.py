"""Sweeps on a Ray cluster: the ``ray`` backend of :mod:`drill_env.sweep`.

Install with ``pip install 'drill-env[distributed]'`` on the machine that runs the sweep
and on every node of the cluster (the nodes import ``drill_env`` to run a task, so they
need the same version). ``ray_address``:

=============  ===========================================================================
``"local"``    start a one-machine Ray instance in this process (the cores it may use,
               a 256 MB object store) and stop it at the end
``"auto"``     join the cluster that ``ray start --head`` started on this machine
an address     join that cluster (``"10.0.0.1:6379"``, ``"ray://host:10001"``)
=============  ===========================================================================

Each item is one Ray task asking for one CPU; at most ``2 x`` the cluster's CPUs are in
flight, so results stream back as they finish and an interrupt leaves little work half
done: the tasks in flight then end by themselves within ``SETTLE_GRACE`` s or are
interrupted (a training run saves its checkpoint). A task whose worker process or node
dies is run again (``MAX_RETRIES`` times); an exception raised by the task itself is
not retried (it would raise again: every task is a pure function of its argument) and
stops the sweep with that error. The results are the same numbers whichever backend ran
them. A task runs in the command's working folder, which on a cluster of several machines
must be one every node mounts at the same path (:func:`_in_folder`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from drill_env.sweep import Late, usable_cores

#: Bytes of shared memory the one-machine Ray (``--ray-address local``) sets aside for
#: its object store. Ray's default is 30 % of the machine's memory, mapped at start: under
#: a 4 GB address-space limit the start failed after 30 s with a raw traceback (an
#: outside check). What the sweeps pass through it is small (settings, controller names,
#: result rows of a few kB), and Ray spills to disk past it; its floor is 75 MB.
LOCAL_OBJECT_STORE = 256 * 1024**2
#: How many times a task whose worker died is resubmitted before the sweep fails.
MAX_RETRIES = 3
#: Workers run one numba / OpenMP thread each: the cluster's CPUs are the parallelism.
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


#: How long the tasks in flight when a sweep stops may take to end by themselves (s), and
#: then, interrupted, to finish what they do on an interrupt (a training run saves a
#: checkpoint: seconds): :meth:`RayExecutor._stop`.
SETTLE_GRACE = 10.0
CANCEL_GRACE = 60.0
#: How long the one connection attempt before ``ray.init`` may take (s): Ray itself
#: retries an address where nothing answers for minutes, printing only its own logs.
CONNECT_TIMEOUT = 5.0


#: A warning a task gave, as it travels back: (text, category, file, line, module).
Said = tuple[str, type, str, int, str | None]


def _call(fn: Callable[[Any], Any], item: Any,
          folder: str | None = None) -> tuple[Any, list[Said]]:
    """``fn(item)`` run in ``folder`` (:func:`_in_folder`), and the warnings it gave: a
    Ray worker's stderr does not reach the command (``log_to_driver=False``), so a warning
    said on local processes (a WOB above the string's limit, a pipe in compression) was
    lost on Ray (an outside check); the driver gives them again (:func:`_said`). Each
    place's first only, as Python's default filter shows them (a warning at every step of
    a training run would be kept a million times), each task's anew (the filters set, the
    worker's registry of what it said counts no more)."""
    import warnings

    _interruptible()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        with _in_folder(folder):
            result = fn(item)
    places = dict.fromkeys((str(w.message), w.category, w.filename, w.lineno)
                           for w in caught)
    return result, [(*place, _module_of(place[2])) for place in places]


@contextlib.contextmanager
def _in_folder(folder: str | None) -> Iterator[None]:
    """Run a task in ``folder``, the command's working folder, where the paths the user
    typed relative to it (``--out``, a run folder, ``learned:RUN``) mean what they meant
    there. A Ray worker starts in the folder its node was started from (``ray start``'s):
    a training sweep's run folders landed there, its summary listing them where they were
    not, and ``evaluate`` found no run (an outside check). A node without the folder (a
    cluster without a shared filesystem) runs the task where it is, and says so."""
    if folder is None:
        yield
    elif os.path.isdir(folder):
        with contextlib.chdir(folder):
            yield
    else:
        import socket
        import warnings

        warnings.warn(f"ray_address: node {socket.gethostname()} has no folder {folder}, "
                      f"the command's: its tasks ran in {os.getcwd()}, where what they "
                      "write by a relative path (run folders, series, recordings) lands; "
                      "on a cluster of several machines, run drill-env from a folder every "
                      "node mounts at the same path (README, Scaling out on Ray)",
                      RuntimeWarning, stacklevel=3)
        yield


def _module_of(filename: str) -> str | None:
    """The name of the module loaded from ``filename``, which a filter by module matches
    (``warnings.filterwarnings(..., module="drill_env.env_config")``): given again with
    the file alone, a warning's module reads as the file's path. None where no loaded
    module has that file (the path then stands for it, as before)."""
    for name, module in list(sys.modules.items()):
        if getattr(module, "__file__", None) == filename:
            return name
    return None


def _said(reply: tuple[Any, list[Said]], registry: dict[Any, Any]) -> Any:
    """The result of a :func:`_call` reply, its warnings given here at their own file and
    line (``registry``: the sweep's, so each place's first is shown once). One that
    cannot be given again (a category not rebuilt from its text, a filter that turns it
    into an error) is printed: the result is kept either way."""
    import warnings

    result, caught = reply
    for text, category, filename, lineno, module in caught:
        try:
            # module=None would drop the warning (CPython's warn_explicit gives nothing
            # for it): leave it out and the file names the module
            if module is None:
                warnings.warn_explicit(text, category, filename, lineno, registry=registry)
            else:
                warnings.warn_explicit(text, category, filename, lineno, module=module,
                                       registry=registry)
        except Exception:  # noqa: BLE001 - the task's result matters more than its warning
            print(f"{filename}:{lineno}: {category.__name__}: {text}", file=sys.stderr)
    return result


def _interruptible() -> None:
    """Let :meth:`RayExecutor._stop` interrupt this task: Ray's cancel reaches a running
    task through Python's SIGINT handler, which a worker does not have when it inherited
    SIGINT ignored (a sweep started as a background job, ``drill-env ... &``, whose shell
    ignores it): the task then ran on until it was killed, a training run unsaved."""
    from drill_env.sweep import hear_interrupts

    hear_interrupts()


def _check_reachable(ray_address: str) -> None:
    """ConnectionError naming the address if ``host:port`` (or ``ray://host:port``;
    ``[v6]:port`` for IPv6) does not accept a TCP connection, or what answers is not a
    gRPC server (:func:`_check_grpc`); other forms (``auto``, another scheme, an address
    without a port) are left to Ray, which names them."""
    import socket

    rest = ray_address.removeprefix("ray://")
    host, colon, port = rest.rpartition(":")
    if "://" in rest or not (colon and host and port.isdigit()) or (
            ":" in host and not (host.startswith("[") and host.endswith("]"))):
        return
    try:
        connection = socket.create_connection((host.strip("[]"), int(port)),
                                              timeout=CONNECT_TIMEOUT)
    except OSError as error:
        raise ConnectionError(f"ray_address: no Ray cluster at {ray_address!r}: nothing "
                              f"answers there ({error}); 'local' starts one here") from None
    with connection:
        if os.environ.get("RAY_USE_TLS", "0").lower() in ("0", "", "false"):
            _check_grpc(connection, ray_address)


#: The client's HTTP/2 connection preface (RFC 9113, 3.4) and an empty SETTINGS frame.
_HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
#: The type of an HTTP/2 SETTINGS frame: a server's first frame (RFC 9113, 3.4).
_HTTP2_SETTINGS = 4


def _check_grpc(connection: Any, ray_address: str) -> None:
    """ConnectionError if what answers at the address is not a gRPC server, as Ray's
    GCS and its client server are: Ray would retry it for ~20 s, printing its own
    errors. A gRPC server answers the HTTP/2 connection preface with a SETTINGS frame
    (its first frame, RFC 9113, 3.4); an SSH or HTTP/1 server says something else or
    closes. (Not asked with TLS, ``RAY_USE_TLS``, where the first bytes are TLS's.)"""
    header, reason, silent = b"", "it closed the connection", False
    try:
        connection.sendall(_HTTP2_PREFACE)
        while len(header) < 4 and (part := connection.recv(9 - len(header))):
            header += part
    except TimeoutError:
        silent = not header
    except OSError as error:
        reason = f"{error}"
    if silent:  # a head too busy to answer in time is not "not Ray"
        raise ConnectionError(f"ray_address: nothing came back from {ray_address!r} in "
                              f"{CONNECT_TIMEOUT:g} s: not a Ray cluster, or one too busy to "
                              "answer")
    if header:
        reason = "it does not speak gRPC"
    if len(header) < 4 or header[3] != _HTTP2_SETTINGS:
        raise ConnectionError(f"ray_address: no Ray cluster at {ray_address!r}: something "
                              f"answers there, but not Ray ({reason}); the address is the "
                              "head's GCS port (6379 by default) or ray://host:10001")


@contextlib.contextmanager
def _quiet_token_notice() -> Iterator[None]:
    """Ray's notice that a new cluster uses token authentication (Ray's default, kept) off
    the console during ``ray.init``: it reads as a warning above our progress bar and
    asks the user to opt out of a safe default."""
    notice = logging.getLogger("ray._private.authentication.authentication_token_setup")
    level = notice.level
    notice.setLevel(logging.ERROR)
    try:
        yield
    finally:
        notice.setLevel(level)


class RayExecutor:
    """Runs a sweep's tasks on Ray; yields ``(index, result)`` as tasks finish."""

    name = "ray"

    def __init__(self, ray_address: str) -> None:
        try:
            import ray
        except ImportError as error:  # pragma: no cover - depends on the install
            raise ImportError("ray_address: Ray is not installed; install the "
                              "'distributed' extra: pip install 'drill-env[distributed]'"
                              ) from error
        if not isinstance(ray_address, str) or not ray_address:
            raise ValueError("ray_address: must be 'local', 'auto' or a cluster address, "
                             f"got {ray_address!r}")
        self._ray = ray
        self._warned: dict[Any, Any] = {}  # what the tasks' warnings said here (_said)
        self._owns = not ray.is_initialized()
        # ray.init sets its own SIGTERM handler (sys.exit(15)) over the command's, which
        # stops a sweep as a Ctrl-C does (finished work kept, exit 143): put it back
        main = threading.current_thread() is threading.main_thread()
        previous = signal.getsignal(signal.SIGTERM) if main else None
        try:
            self._init(ray, ray_address)
        finally:
            if main and previous is not None:
                signal.signal(signal.SIGTERM, previous)
        self._remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES,
                                  retry_exceptions=False)(_call)

    def _init(self, ray: Any, ray_address: str) -> None:
        """Start (``local``) or join the Ray session, unless one is running."""
        if self._owns:
            runtime_env = {"env_vars": dict(WORKER_ENV)}
            if ray_address == "local":
                # address="local": a new private instance even where a cluster runs (without
                # it Ray joins that cluster and refuses num_cpus)
                with _quiet_token_notice():
                    ray.init(address="local", num_cpus=usable_cores(),
                             object_store_memory=LOCAL_OBJECT_STORE,
                             include_dashboard=False, runtime_env=runtime_env,
                             log_to_driver=False, configure_logging=False)
            else:
                # Ray's C++ core logs every failed connection attempt at WARNING: keep the
                # console for our progress bar and one clear error (not for "local", which
                # makes no attempts: the variable costs a line of its own there)
                os.environ.setdefault("RAY_BACKEND_LOG_LEVEL", "error")
                if ray_address.startswith(("http://", "https://")):
                    # (Ray's own refusal tells how to fix a RAY_ADDRESS nobody set)
                    raise ValueError(f"ray_address: {ray_address!r} is a web address (a "
                                     "dashboard's or job server's); join the head's GCS "
                                     "address host:port (6379 by default: `ray start "
                                     "--head` prints it), ray://host:10001, 'auto' on the "
                                     "head, or 'local'")
                _check_reachable(ray_address)
                try:
                    with _quiet_token_notice():
                        ray.init(address=ray_address, runtime_env=runtime_env,
                                 log_to_driver=False, configure_logging=False)
                except ConnectionError as error:
                    if ray_address == "auto" and "Could not find any running Ray" in str(
                            error):  # (Ray's advice names its own --address flag)
                        raise ConnectionError(
                            "ray_address: 'auto' found no Ray cluster started on this "
                            "machine: `ray start --head` starts one to join, and 'local' "
                            "one for this command alone") from None
                    # `ray start` (Ray >= 2.59) turns token authentication on wherever
                    # ~/.ray/auth_token exists, which a `local` run writes; Ray sends the
                    # token to `auto` but to an address only with RAY_AUTH_MODE=token (it
                    # does not hand a secret to an address unasked, nor do we): the join
                    # failed after ~20 s as "no Ray cluster" (an outside check)
                    hint = "" if os.environ.get("RAY_AUTH_MODE") == "token" else (
                        "; if the cluster uses token authentication (Ray's default for "
                        "`ray start` from 2.59), Ray sends your token only to 'auto' or "
                        "with RAY_AUTH_MODE=token set (the token from RAY_AUTH_TOKEN or "
                        "~/.ray/auth_token; `ray get-auth-token` prints the head's)")
                    raise ConnectionError(f"ray_address: could not join a Ray cluster at "
                                          f"{ray_address!r} ({error}){hint}") from error
                except ValueError as error:  # not an address at all ("Invalid address ...")
                    raise ValueError(f"ray_address: {ray_address!r} is not 'local', 'auto' "
                                     f"or a cluster address host:port ({error})") from None

    @property
    def cpus(self) -> int:
        """The cluster's CPUs now (at least 1)."""
        return max(1, int(self._ray.cluster_resources().get("CPU", 1)))

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any],
                      late: Late | None = None) -> Iterator[tuple[int, Any]]:
        ray = self._ray
        fn_ref = ray.put(fn)
        folder = os.getcwd()  # the tasks' (_in_folder)
        pending = iter(enumerate(items))
        in_flight: dict[Any, int] = {}
        limit = 2 * self.cpus
        try:
            for k, item in pending:
                in_flight[self._remote.remote(fn_ref, item, folder)] = k
                if len(in_flight) >= limit:
                    break
            while in_flight:
                done, _ = ray.wait(list(in_flight), num_returns=1)
                for ref in done:
                    k = in_flight.pop(ref)
                    yield k, _said(ray.get(ref), self._warned)
                    for k_next, item in pending:
                        in_flight[self._remote.remote(fn_ref, item, folder)] = k_next
                        break
        finally:
            if ray.is_initialized() and in_flight:  # not after close(): that session's refs
                self._stop(in_flight, late)

    def _stop(self, in_flight: dict[Any, int], late: Late | None = None) -> None:
        """End the tasks ``in_flight`` (ref -> index) of a stopped sweep. Those that end within
        ``SETTLE_GRACE`` s (a benchmark episode, a map point) are left to: cancelling a
        task as its reply comes in trips a check in Ray's task manager (the driver died
        with it, or segfaulted, about one Ctrl-C in four; ray-project/ray#54798). A task
        still running then (a training run) gets a KeyboardInterrupt, as a local worker
        does (a training run saves its checkpoint on it, which killing its worker lost),
        and its worker is killed only after ``CANCEL_GRACE`` s more. Those cancels can
        still meet a reply: rarer (a task that runs that long replies seldom), not
        impossible. A second Ctrl-C, or an error of Ray's while waiting, stops what is
        left at once. What ends before or during the wait goes to ``late`` (index,
        result), for the sweep to keep: a rerun need not do it again."""
        ray = self._ray
        refs = list(in_flight)
        running = refs

        def keep(ready: list[Any]) -> None:
            if late is None:
                return
            for ref in ready:
                try:
                    result = _said(ray.get(ref, timeout=0.0), self._warned)
                except Exception:  # noqa: BLE001 - a failed task: nothing to keep
                    continue
                late(in_flight[ref], result)

        try:
            ready, running = ray.wait(refs, num_returns=len(refs), timeout=0.0)
            keep(ready)
            if running:
                print(f"stopping: {len(running)} Ray tasks in flight; {SETTLE_GRACE:g} s "
                      "to end by themselves, then interrupted (a training run saves its "
                      f"checkpoint) and killed after {CANCEL_GRACE:g} s more; a second "
                      "interrupt (Ctrl-C) kills them now", file=sys.stderr)
                ready, running = ray.wait(running, num_returns=len(running),
                                          timeout=SETTLE_GRACE)
                keep(ready)
            if running:
                for ref in running:
                    ray.cancel(ref, force=False)
                _, running = ray.wait(running, num_returns=len(running),
                                      timeout=CANCEL_GRACE)
        except BaseException:  # a second Ctrl-C, a lost cluster: stop what is left now
            with contextlib.suppress(Exception):
                for ref in running:
                    ray.cancel(ref, force=True)
            raise
        for ref in running:
            ray.cancel(ref, force=True)

    def close(self) -> None:
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
