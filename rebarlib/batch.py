"""Many captures at once: :func:`inspect_many` runs ``inspect`` over a batch of captures.

The captures are inspected in local worker processes (``jobs``) or on the workers of a
``dask.distributed`` cluster (``client``); each outcome is handed back as soon as its capture is
done (or in input order, ``ordered=True``). A capture that fails is reported as a failed
:class:`Outcome` with a one-line cause, and the others go on.

Workers read the captures themselves, from the paths given (on a cluster the path must be one
the workers share with the caller); only the results travel back. Every worker's segmentation
model runs on one thread (:data:`WORKER_THREADS`), so ``jobs`` processes use ``jobs`` cores
and a dask worker runs as many inspections at once as it has threads.

This module imports nothing heavy at import time: the command line loads it before it knows
whether any capture needs computing.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "Outcome",
    "inspect_many",
    "inspect_pairs",
    "inspect_one",
    "summary_row",
    "summary_table",
    "SUMMARY_COLUMNS",
    "default_jobs",
    "WORKER_THREADS",
]

#: Threads of the segmentation model (onnxruntime) and of OpenCV in a batch worker: one task,
#: one core. The results do not depend on it (``benchmarks/bench_batch.py --check``).
WORKER_THREADS = 1
#: Tasks kept in flight per worker (process or dask thread): enough to keep each one busy
#: while the caller writes the last result, few enough that a batch of thousands of captures
#: neither pickles all its tasks up front nor holds their results.
IN_FLIGHT_PER_WORKER = 2


@dataclass
class Outcome:
    """What became of one capture of a batch.

    Attributes
    ----------
    index : position of the capture in the list given to :func:`inspect_many`
    capture : the capture's name (its folder's name)
    path : the capture folder as given (None for a ``Capture`` object)
    result : the :class:`~rebarlib.InspectionResult`, or None where it failed
    error : one line saying why it failed, or None
    seconds : wall time of loading and inspecting it, in the worker
    """

    index: int
    capture: str
    path: str | None
    result: object = None
    error: str | None = None
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        """True where the capture was inspected."""
        return self.error is None


#: Columns of a batch's summary (``OUT/summary.csv``, :func:`summary_table`).
SUMMARY_COLUMNS = (
    "capture",
    "status",
    "cover_mm",
    "layer_distance_mm",
    "worst_spacing_deviation_mm",
    "seconds",
    "reason",
)


def _worst_deviation(spacings):
    devs = [s.get("deviation_mm") for s in spacings or [] if isinstance(s, dict)]
    devs = [d for d in devs if isinstance(d, (int, float))]
    return max(devs, key=abs) if devs else None


def summary_row(name: str, status: str, data: dict | None = None, seconds=None, reason: str = "") -> dict:
    """One row of a batch summary from a result dict (``InspectionResult.to_dict()`` or a
    ``result.json``): cover, layer distance, the spacing deviation largest in size (signed),
    mm as the result rounds them; ``seconds`` as text with 2 decimals ("" where not computed).

    Parameters
    ----------
    name : str
        The capture's name.
    status : str
        "ok" or "failed".
    data : dict or None
        The result as a dict; None for a failed capture.
    seconds : float or None
        The time the capture took.
    reason : str
        Why it failed ("" where it did not).

    Returns
    -------
    dict
        Keys :data:`SUMMARY_COLUMNS`.

    Examples
    --------
    >>> row = summary_row("A_400", "ok", {"cover_mm": 25.1, "spacings": [{"deviation_mm": -3.2},
    ...                   {"deviation_mm": 4.0}]}, seconds=1.234)
    >>> row["worst_spacing_deviation_mm"], row["seconds"], row["layer_distance_mm"]
    (4.0, '1.23', None)
    """
    data = data or {}
    sec = "" if seconds is None else f"{seconds:.2f}"
    return {
        "capture": name,
        "status": status,
        "cover_mm": data.get("cover_mm"),
        "layer_distance_mm": data.get("layer_distance_mm"),
        "worst_spacing_deviation_mm": _worst_deviation(data.get("spacings")),
        "seconds": sec,
        "reason": reason,
    }


def summary_table(outcomes):
    """A pandas DataFrame with one :func:`summary_row` per outcome (status "ok" or "failed"),
    in the order of the captures.

    Parameters
    ----------
    outcomes : iterable of Outcome
        As :func:`inspect_many` yields them, in any order.

    Returns
    -------
    DataFrame
        Columns :data:`SUMMARY_COLUMNS`; ``seconds`` numeric (NaN where not computed).
    """
    import pandas as pd

    rows = [
        summary_row(
            o.capture, "ok" if o.ok else "failed", o.result.to_dict() if o.ok else None, o.seconds, o.error or ""
        )
        for o in sorted(outcomes, key=lambda o: o.index)
    ]
    table = pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))
    table["seconds"] = pd.to_numeric(table["seconds"])
    return table


def default_jobs() -> int:
    """The cores this process may run on (all of them by default).

    Returns
    -------
    int
        At least 1.
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _one_line(exc: BaseException) -> str:
    """A failure as one line: the message of an input error, else the type and first line."""
    from ._checks import RebarInputError

    lines = str(exc).strip().splitlines()
    first = lines[0].strip() if lines else ""
    if isinstance(exc, RebarInputError):
        return first or "invalid input"
    return f"{type(exc).__name__}: {first}" if first else type(exc).__name__


def _capture_name(capture) -> str:
    if isinstance(capture, (str, os.PathLike)):
        return Path(capture).resolve().name
    return str(getattr(capture, "name", "") or "capture")


_configured_threads = None


def _configure_threads(threads) -> None:
    """Set the segmentation model's, OpenCV's and the BLAS library's threads in this process
    (once per value).

    BLAS (numpy's and scipy's OpenBLAS) starts a thread per core by default. The geometry's
    matrix products are small (a few hundred thousand points times a 3 x 3 matrix): split over
    threads while the batch's other workers keep every core busy, each product waits for a
    thread to be scheduled, and the waiting threads spin. One BLAS thread per worker gives the
    same numbers (OpenBLAS splits a product's rows, not its sums, over its threads: the example
    captures' results are identical either way) for 0.10-0.15 CPU s less per capture at full
    load (docs/batch.md, "Speed")."""
    global _configured_threads
    if threads is None or threads == _configured_threads:
        return
    import cv2
    from threadpoolctl import threadpool_limits

    from . import _masks

    cv2.setNumThreads(int(threads))
    threadpool_limits(limits=int(threads), user_api="blas")
    if _masks.MODEL_THREADS != threads:
        _masks.MODEL_THREADS = int(threads)
        _masks._default_model.cache_clear()
    _configured_threads = threads


def inspect_one(index: int, capture, design, inspect_kw: dict | None = None, *, threads=None) -> Outcome:
    """Load and inspect one capture; never raises for a failure of that capture.

    Parameters
    ----------
    index : the capture's position in its batch (carried into the :class:`Outcome`)
    capture : a capture folder (str or Path) or a :class:`~rebarlib.Capture`
    design : :class:`~rebarlib.Design`
    inspect_kw : keyword arguments of :func:`rebarlib.inspect`
    threads : threads for the segmentation model and OpenCV in this process (None: as set)

    Returns
    -------
    Outcome with the result, or with ``error`` (one line) where it failed.
    """
    t0 = time.perf_counter()
    name = _capture_name(capture)
    path = str(capture) if isinstance(capture, (str, os.PathLike)) else None
    try:
        _configure_threads(threads)
        from ._capture import load_capture
        from ._inspect import inspect

        cap = load_capture(capture) if path is not None else capture
        res = inspect(cap, design, **(inspect_kw or {}))
        res.capture = name
    except Exception as exc:  # one capture's failure, whatever it is, is that capture's outcome
        return Outcome(index, name, path, None, _one_line(exc), time.perf_counter() - t0)
    return Outcome(index, name, path, res, None, time.perf_counter() - t0)


def _check_args(design, jobs, client, inspect_kw):
    from ._checks import RebarInputError
    from ._design import Design, load_design

    if isinstance(design, (str, os.PathLike)):
        design = load_design(design)
    if not isinstance(design, Design):
        raise RebarInputError(f"design: expected a rebarlib.Design or a design.toml path, got {type(design).__name__}")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise RebarInputError(f"jobs: expected a whole number of processes >= 1, got {jobs!r}")
    if jobs is not None and client is not None:
        raise RebarInputError("jobs: give either jobs (local processes) or client (a dask cluster), not both")
    rng = inspect_kw.get("rng")
    if rng is not None and (isinstance(rng, bool) or not isinstance(rng, int)):
        raise RebarInputError(
            f"rng: a batch inspects every capture with the same whole-number seed, got {type(rng).__name__}"
        )
    return design


def inspect_many(captures, design, *, client=None, jobs=None, ordered: bool = False, progress=None, **inspect_kw):
    """Inspect many captures; yield one :class:`Outcome` per capture as each is done.

    Parameters
    ----------
    captures : iterable of capture folders (str or Path) or :class:`~rebarlib.Capture` objects
        (objects are sent whole to the workers; folders are read by the workers)
    design : :class:`~rebarlib.Design` or the path of a ``design.toml``
    client : a ``distributed.Client`` or a scheduler address (``"tcp://host:8786"``): inspect on
        that dask cluster, whose workers must see the capture folders at the same paths
    jobs : local worker processes (default: all cores); 1 inspects in this process, one by one
    ordered : yield in the order of ``captures`` instead of as they finish
    progress : called as ``progress(outcome, done, total)`` when each capture is done
    **inspect_kw : passed to :func:`rebarlib.inspect` (``method``, ``diameters``, ``mask_source``,
        ``rng``: a whole-number seed, used for every capture)

    Yields
    ------
    Outcome: ``result`` where it was inspected, else ``error``, the cause in one line. An error
    of one capture does not stop the others.

    Raises
    ------
    RebarInputError
        For arguments that fit no capture (a design that is not one, ``jobs`` < 1, both
        ``jobs`` and ``client``, a seed that is not a whole number).

    Examples
    --------
    >>> from rebarlib.data import example_capture, example_slab
    >>> _, design = example_slab("paper_slab")
    >>> [o.capture for o in inspect_many([example_capture("paper_slab", "A_400")], design, jobs=1,
    ...                                  diameters=False, rng=0)]
    ['A_400']
    """
    design = _check_args(design, jobs, client, inspect_kw)
    return _drive([(c, design) for c in captures], client, jobs, ordered, progress, inspect_kw)


def inspect_pairs(pairs, *, client=None, jobs=None, ordered: bool = False, progress=None, **inspect_kw):
    """:func:`inspect_many` over ``(capture, design)`` pairs: captures of several slabs at once.

    Parameters
    ----------
    pairs : iterable of (capture, design)
        Each capture (a folder or a :class:`~rebarlib.Capture`) with its own design (a
        :class:`~rebarlib.Design` or the path of a ``design.toml``).
    client, jobs, ordered, progress, **inspect_kw
        As for :func:`inspect_many`.

    Yields
    ------
    Outcome
        One per pair, as for :func:`inspect_many`.
    """
    pairs = [(c, _check_args(d, jobs, client, inspect_kw)) for c, d in pairs]
    return _drive(pairs, client, jobs, ordered, progress, inspect_kw)


def _drive(pairs, client, jobs, ordered, progress, inspect_kw):
    items = [(i, c, d) for i, (c, d) in enumerate(pairs)]
    total = len(items)
    if client is not None:
        stream = _on_dask(items, client, inspect_kw)
    elif min(jobs or default_jobs(), total) <= 1:
        stream = (inspect_one(i, c, d, inspect_kw) for i, c, d in items)
    else:
        stream = _in_processes(items, min(jobs or default_jobs(), total), inspect_kw)
    stream = _counted(stream, total, progress)
    yield from (_in_input_order(stream) if ordered else stream)


def _counted(stream, total, progress):
    for done, outcome in enumerate(stream, start=1):
        if progress is not None:
            progress(outcome, done, total)
        yield outcome


def _in_input_order(stream):
    waiting, next_index = {}, 0
    for outcome in stream:
        waiting[outcome.index] = outcome
        while next_index in waiting:
            yield waiting.pop(next_index)
            next_index += 1
    yield from (waiting[i] for i in sorted(waiting))


def _failed(index, capture, exc) -> Outcome:
    path = str(capture) if isinstance(capture, (str, os.PathLike)) else None
    return Outcome(index, _capture_name(capture), path, None, _one_line(exc), 0.0)


def _init_worker(threads):
    os.environ["OMP_NUM_THREADS"] = str(threads)  # Open3D's OpenMP loops, if not yet started
    _configure_threads(threads)
    # import the stages now, so that a capture's seconds are its own, not the worker's start-up
    from . import _inspect, diameter  # noqa: F401


def _in_processes(items, jobs, inspect_kw):
    """Outcomes from ``jobs`` local processes, ``IN_FLIGHT_PER_WORKER`` tasks each in flight."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    # spawn, not fork: the caller (a notebook, a server) may hold threads that a fork would copy
    # half-way; the workers start from a clean interpreter and import what they need once
    ctx = multiprocessing.get_context("spawn")
    todo = iter(items)
    running = {}
    with ProcessPoolExecutor(
        max_workers=jobs, mp_context=ctx, initializer=_init_worker, initargs=(WORKER_THREADS,)
    ) as pool:
        try:

            def submit(i, c, d):
                fut = pool.submit(inspect_one, i, c, d, inspect_kw, threads=WORKER_THREADS)
                running[fut] = (i, c)

            for item in _take(todo, jobs * IN_FLIGHT_PER_WORKER):
                submit(*item)
            while running:
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in done:
                    i, c = running.pop(fut)
                    try:
                        outcome = fut.result()
                    except Exception as exc:  # the worker died, or the result could not come back
                        outcome = _failed(i, c, exc)
                    del fut
                    for item in _take(todo, 1):
                        submit(*item)
                    yield outcome
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _take(iterator, n):
    out = []
    for _ in range(n):
        try:
            out.append(next(iterator))
        except StopIteration:
            break
    return out


def _on_dask(items, client, inspect_kw):
    """Outcomes from a dask.distributed cluster (``client``: a Client or a scheduler address)."""
    from distributed import Client, as_completed

    own = not isinstance(client, Client)
    if own:
        client = Client(str(client), set_as_default=False)
    try:
        # folders go as absolute paths: the workers' working folder is not the caller's
        items = [(i, str(Path(c).resolve()) if isinstance(c, (str, os.PathLike)) else c, d) for i, c, d in items]
        width = max(2, IN_FLIGHT_PER_WORKER * sum(client.nthreads().values()))
        todo = iter(items)
        designs = {}  # each design sent to the workers once
        running = {}

        def submit(i, c, d):
            if id(d) not in designs:
                designs[id(d)] = client.scatter(d, broadcast=True)
            fut = client.submit(inspect_one, i, c, designs[id(d)], inspect_kw, threads=WORKER_THREADS, pure=False)
            running[fut.key] = (i, c)
            return fut

        queue = as_completed([submit(*item) for item in _take(todo, width)], loop=client.loop)
        for fut in queue:
            i, c = running.pop(fut.key)
            try:
                outcome = fut.result()
            except Exception as exc:  # the worker was lost, or the result could not come back
                outcome = _failed(i, c, exc)
            fut.release()
            for item in _take(todo, 1):
                queue.add(submit(*item))
            yield outcome
    finally:
        if own:
            client.close()
