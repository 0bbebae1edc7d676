"""Where a streamed export's tiles are rendered: worker processes (a pool of
spawned interpreters, each with its own headless GL context) or a Dask
cluster. Workers receive a picklable ``worker_init`` that builds their
Synthesizer (:class:`ProjectSynthesizer`: the project as JSON, never engine
objects) and return the encoded tile bytes; the exporting process writes them.
"""
from __future__ import annotations

import os
import re
import secrets
import threading
import time
from dataclasses import dataclass, replace

from infinitex.engine.analysis import analyze
from infinitex.engine.pyramid import Rect
from infinitex.engine.safeio import printable
from infinitex.engine.synth import Synthesizer
from infinitex.project import parse_project_json, project_from_json
from infinitex.project.realize import exemplar_for, material_or_none

from .errors import ExportFailed
from .formats import encode_tile


@dataclass
class ProjectSynthesizer:
    """Makes, in another process, the Synthesizer of a project: what export
    workers receive (the project as JSON with its exemplar embedded, not
    pickled engine objects). Each worker has its own headless GL context."""

    project_json: str
    period: int = 0
    role: str = ""  # a material's map the tiles show ("": the first map)

    def __call__(self) -> Synthesizer:
        doc = project_from_json(parse_project_json(self.project_json.encode("utf-8"))).document
        material = material_or_none(doc)
        ex, settings = exemplar_for(doc, material=material)
        an = analyze(ex, settings)  # the disk cache holds it: the parent analyzed it already
        params = doc.params(an.L)
        if self.period:
            params = replace(params, period=self.period)
        synth = Synthesizer(an, params, controls=doc.controls(an.size))
        if material is not None:
            synth.palette = material.stack(self.role or material.primary)
            synth.normals = (self.role or material.primary) == "normal"  # turned with a direction field
        return synth


def calibrate(worker_init, fmt: str, tile: int) -> tuple[float, float]:
    """Seconds and bytes per pixel of a streamed export, measured on one tile
    (at most 1024 px; larger tiles cost about the same per pixel) rendered
    and encoded as the export does, in a worker made by ``worker_init``."""
    synth = worker_init()
    n = min(tile, 1024)
    # A first tile of the same size compiles the shaders and allocates the
    # buffers: costs an export pays once, not per pixel.
    encode_tile(synth, fmt, n, Rect(-n, 0, 0, n))
    t0 = time.perf_counter()
    blob = encode_tile(synth, fmt, n, Rect(n, 3 * n, 2 * n, 4 * n))[0]
    return (time.perf_counter() - t0) / (n * n), len(blob) / (n * n)


def in_flight(workers: int) -> int:
    return 2 * max(1, workers) + 2  # enough to keep the workers busy; a cancel drops the rest at once


def run_pool(job, todo, workers: int, worker_init, finished) -> None:
    """Tiles rendered by ``workers`` spawned processes; a pool whose worker dies
    is replaced and its tiles rendered again."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool
    ctx = multiprocessing.get_context("spawn")  # a fresh interpreter: no inherited GL state
    retry: list = []  # tiles of a pool that broke (a worker died)
    restarts = 0
    more = True
    while more or retry:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_start,
                                   initargs=(worker_init,))
        futures: dict = {}
        broken = False
        try:
            while True:
                while len(futures) < in_flight(workers) and (retry or more):
                    item = retry.pop() if retry else next(todo, None)
                    if item is None:
                        more = False
                        break
                    try:
                        fut = pool.submit(_worker_tile, job.fmt, job.tile, _box(item[2]), job.coords, item[3])
                    except BrokenProcessPool:  # a worker died since the last wait: this pool is done
                        retry.append(item)
                        broken = True
                        break
                    futures[fut] = item
                if broken:
                    retry.extend(futures.values())
                    break
                if not futures:
                    break
                ready, _ = wait(futures, return_when=FIRST_COMPLETED)
                for fut in ready:
                    item = futures.pop(fut)
                    try:
                        blobs = fut.result()
                    except BrokenProcessPool:
                        broken = True
                        retry.append(item)
                        continue
                    finished(item, blobs)
                if broken:
                    retry.extend(futures.values())
                    break
        finally:  # stopped (or done): drop the queued tiles, wait only for those being rendered
            pool.shutdown(wait=True, cancel_futures=True)
        if broken:
            restarts += 1
            if restarts > 3 * workers + 3:
                raise ExportFailed("The export's worker processes keep dying (out of memory?); the finished "
                                   "tiles are kept: run the same export again to continue.")

SCHEDULER_TIMEOUT_S = 10.0  # the whole connection to a Dask scheduler: TCP, handshake and first reply
_ADDRESS = re.compile(r"^(?:[Tt][Cc][Pp]://)?(?P<host>\[[0-9A-Fa-f:.]{2,45}\]|[A-Za-z0-9._-]{1,253}):(?P<port>[0-9]{1,5})$")
_SCHEME = re.compile(r"^(?P<scheme>[A-Za-z][A-Za-z0-9+.-]{0,15})://")


def check_scheduler_address(address: str) -> str:
    """A Dask scheduler's address as ``tcp://HOST:PORT`` (given so, or as
    ``HOST:PORT``), or ``"local"`` (a LocalCluster); ValueError with a sentence
    for anything else: an empty address, another transport (tls://, ucx://,
    inproc://, ws://... are not set up here), no port."""
    if address == "local":
        return address
    text = address.strip()
    if not text:
        raise ValueError("--scheduler needs an address (tcp://HOST:PORT), or nothing at all for a LocalCluster; "
                         "it is empty.")
    m = _SCHEME.match(text)
    if m and m.group("scheme").lower() != "tcp":
        raise ValueError(f"The Dask scheduler address {printable(text, 80)} uses {printable(m.group('scheme'), 20)}://; "
                         "only tcp://HOST:PORT addresses are supported.")
    m = _ADDRESS.match(text)
    if not m or not 1 <= int(m.group("port")) <= 65535:
        raise ValueError(f"{printable(text, 80)} is not a Dask scheduler address: give tcp://HOST:PORT "
                         "(e.g. tcp://10.0.0.5:8786).")
    return f"tcp://{m.group('host')}:{int(m.group('port'))}"


async def _identity(address: str, timeout: float) -> dict:
    """The scheduler's identity, asked over distributed's own comm (not
    deserializing anything but plain messages)."""
    import asyncio

    from distributed.comm import connect
    comm = await connect(address, timeout=timeout / 2, deserialize=False)  # refused: OSError, retried half the time
    try:
        await comm.write({"op": "identity", "reply": True, "n_workers": 0})
        return await asyncio.wait_for(comm.read(), timeout)
    finally:
        comm.abort()


def probe_scheduler(address: str, timeout: float = SCHEDULER_TIMEOUT_S) -> str:
    """Check, within ``timeout`` seconds in all, that a Dask scheduler answers
    at ``address`` (a port that accepts and says nothing, or answers
    anything but Dask, is not one); returns the address as tcp://HOST:PORT.
    ExportFailed with one sentence naming the address otherwise.
    (``Client(address, timeout=...)`` alone waits forever for a handshake
    that never comes, and reads an HTTP answer as a frame exabytes long.)"""
    import asyncio
    try:
        address = check_scheduler_address(address)
    except ValueError as exc:
        raise ExportFailed(str(exc)) from None
    shown = printable(address, 120)
    result: dict = {}

    def attempt() -> None:
        try:
            import socket

            import distributed.comm  # noqa: F401  (imported before the clock starts: seconds under load)
            host, port = address[len("tcp://"):].rsplit(":", 1)
            # A plain connection first: a refused or unreachable port answers at once (distributed's own
            # connect retries a refusal for half the time, which a loaded machine could spend importing).
            socket.create_connection((host.strip("[]"), int(port)), timeout).close()
            result["reply"] = asyncio.run(asyncio.wait_for(_identity(address, timeout), timeout))
        except BaseException as exc:  # noqa: BLE001 - reported below as one sentence, in the caller's thread
            result["error"] = exc
    # A thread of its own: the deadline holds even for what asyncio cannot
    # cancel (a name lookup); the thread, stuck, would end with the process.
    thread = threading.Thread(target=attempt, name="dask-probe", daemon=True)
    thread.start()
    thread.join(timeout + 2.0)
    error = result.get("error")
    if thread.is_alive() or isinstance(error, (TimeoutError, asyncio.TimeoutError)):
        raise ExportFailed(f"The Dask scheduler at {shown} did not answer within {timeout:g} s "
                           "(is a Dask scheduler listening there?).")
    if isinstance(error, OSError):  # refused, unreachable, closed
        raise ExportFailed(f"Cannot reach the Dask scheduler at {shown}: "
                           f"{printable(getattr(error, 'strerror', None) or error, 200)}") from None
    reply = result.get("reply")
    if error is not None or not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise ExportFailed(f"What answers at {shown} is not a Dask scheduler (it does not speak the Dask "
                           "protocol); check the address and port.")
    return address


def _connect(scheduler: str, workers: int):
    """(client, cluster or None): a LocalCluster's client, or a remote
    scheduler's, connected within a bounded time; ExportFailed otherwise."""
    import logging

    from distributed import Client, LocalCluster
    if scheduler == "local":
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                               processes=True, dashboard_address=None, silence_logs=logging.ERROR)
        try:
            return Client(cluster), cluster
        except BaseException:
            cluster.close()
            raise
    address = probe_scheduler(scheduler)
    result: dict = {}

    def attempt() -> None:
        try:
            result["client"] = Client(address, timeout=SCHEDULER_TIMEOUT_S)
        except BaseException as exc:  # noqa: BLE001 - reported below as one sentence, in the caller's thread
            result["error"] = exc
    thread = threading.Thread(target=attempt, name="dask-connect", daemon=True)
    thread.start()
    thread.join(2 * SCHEDULER_TIMEOUT_S + 5.0)
    if thread.is_alive():
        raise ExportFailed(f"The Dask scheduler at {printable(address, 120)} answered, then did not take this "
                           f"client within {2 * SCHEDULER_TIMEOUT_S:g} s.")
    if "error" in result:
        exc = result["error"]
        raise ExportFailed(f"Cannot connect to the Dask scheduler at {printable(address, 120)}: "
                           f"{printable(exc, 200) or type(exc).__name__}") from None
    return result["client"], None


def run_dask(job, todo, scheduler: str, workers: int, worker_init, finished) -> None:
    """Tiles as Dask tasks: the cluster reschedules those of a worker that dies."""
    from distributed import KilledWorker, as_completed
    from distributed.client import FutureCancelledError
    try:
        client, cluster = _connect(scheduler, workers)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ExportFailed(f"Cannot start or reach the Dask scheduler at {printable(scheduler, 120)}: "
                           f"{printable(exc, 200)}") from None
    try:
        init = client.scatter(worker_init, broadcast=True, hash=False)
        key = job.export_key()
        threads = sum(client.nthreads().values()) or 1
        futures: dict = {}
        serial = [0]
        run_id = secrets.token_hex(4)  # task names of this run only, on a cluster others may share

        def submit() -> bool:
            item = next(todo, None)
            if item is None:
                return False
            serial[0] += 1
            fut = client.submit(_dask_tile, init, key, job.fmt, job.tile, _box(item[2]), job.coords, item[3],
                                pure=False, key=f"infinitex-tile-{key[:12]}-{run_id}-{serial[0]}")
            futures[fut] = item
            queue.add(fut)
            return True
        queue = as_completed([])
        more = True
        while more and len(futures) < in_flight(threads):
            more = submit()
        try:
            for fut in queue:
                item = futures.pop(fut)
                try:
                    blobs = fut.result()
                except FutureCancelledError:
                    continue
                except KilledWorker:
                    raise ExportFailed("A tile killed every Dask worker it was given to (out of memory?); "
                                       "the finished tiles are kept: run the same export again to "
                                       "continue.") from None
                finished(item, blobs)
                while more and len(futures) < in_flight(threads):
                    more = submit()
        except BaseException:
            client.cancel(list(futures))
            raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _box(r: Rect) -> tuple[int, int, int, int]:
    return r.x0, r.y0, r.x1, r.y1


_WORKER: dict = {}


def _worker_start(worker_init) -> None:
    _WORKER["synth"] = worker_init()


def _worker_tile(fmt: str, tile: int, box: tuple[int, int, int, int], coords: bool,
                 level: int | None = None) -> list[bytes]:
    return encode_tile(_WORKER["synth"], fmt, tile, Rect(*box), coords, level)


def _dask_tile(worker_init, key: str, fmt: str, tile: int, box: tuple[int, int, int, int],
               coords: bool, level: int | None = None) -> list[bytes]:
    """A Dask task: the worker's Synthesizer is made once per export and
    thread (a GL context is current in the thread that made it)."""
    slot = (threading.get_ident(), key)
    synth = _WORKER.get(slot)
    if synth is None:
        for old in [k for k in _WORKER if isinstance(k, tuple) and k[0] == slot[0]]:
            _WORKER.pop(old)  # one export's engine per thread at a time
        synth = _WORKER[slot] = worker_init()
    return encode_tile(synth, fmt, tile, Rect(*box), coords, level)
