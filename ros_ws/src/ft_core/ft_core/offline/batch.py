"""One execution layer for every batch tool: a local process pool, or a Dask cluster.

`ft-campaign`, `ft-map`, `ft-plan` and `ft-design` (`dh --verify`, `multicase`) run many
independent jobs. Each takes the same two options (`add_arguments`): `--workers N`
processes on this machine (the default: every core, nothing to set up), or
`--cluster ADDRESS`, the scheduler of a Dask distributed cluster (`tcp://host:8786`),
whose workers run the jobs on as many machines as it has. Dask, not a scheduler of our
own: it reruns a job whose worker died on another worker (a job counts once: the
client takes each job's result once, by its key), sends every result back to the
client (the tool writes it where the user runs it, never on a worker's disk) and shows
the jobs in its dashboard. Ray would do as well; Dask needs no daemon on the client
and its scheduler and workers are two commands (docs/campaign.md, "Past one machine").

`run` yields each job's outcome as it finishes, with a progress bar (jobs done,
failed, time left). Ctrl-C stops the jobs: locally the workers are told (SIGINT, as a
terminal's Ctrl-C tells its whole process group, so `kill -INT` of the tool alone
stops them too: `workers.SPAWN`), on a cluster the jobs are cancelled.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any

from tqdm import tqdm

from ft_core.offline import cli
from ft_core.workers import SPAWN

#: s to wait for a cluster's scheduler to answer.
CONNECT_TIMEOUT = 10.0


@dataclass(frozen=True)
class Where:
    """Where the jobs run: `workers` local processes, or the Dask cluster at `cluster`."""

    workers: int = 1
    cluster: str | None = None

    def describe(self) -> str:
        """'on 2 workers' or 'on the Dask cluster at tcp://...'."""
        return (f"on the Dask cluster at {self.cluster}" if self.cluster
                else f"on {self.workers} worker{'s' if self.workers > 1 else ''}")

    @classmethod
    def from_arguments(cls, args: argparse.Namespace) -> Where:
        """From the options `add_arguments` adds."""
        return cls(args.workers, args.cluster or None)


#: One worker, this process: jobs run one after the other, no pool.
HERE = Where()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """`--workers` and `--cluster`, the same in every batch tool."""
    parser.add_argument("--workers", **cli.workers(os.cpu_count() or 1),
                        help="worker processes on this machine (default: one per core)")
    parser.add_argument("--cluster", metavar="ADDRESS", default=None,
                        help="run on the Dask cluster whose scheduler is at ADDRESS "
                        "(tcp://host:8786) instead (docs/campaign.md)")


@dataclass(frozen=True)
class Outcome:
    """A finished job: its index in the jobs given, and its result or the error it raised."""

    index: int
    result: Any = None
    error: BaseException | None = None


def run(function: Callable[[Any], Any], jobs: Sequence[Any], where: Where, what: str = "job",
        ) -> Iterator[Outcome]:
    """`function(job)` for every job, each outcome as it finishes (in any order).

    `function` must be a module-level function (pickled by reference) and each job
    picklable. One worker locally runs the jobs in this process (no pool to start).
    `what` names a job on the progress bar.
    """
    with tqdm(total=len(jobs), unit=what, disable=None, file=sys.stderr) as bar:
        failed = 0
        if where.cluster:
            outcomes = _on_cluster(function, jobs, where.cluster)
        elif where.workers == 1 or len(jobs) <= 1:
            outcomes = _here(function, jobs)
        else:
            outcomes = _in_pool(function, jobs, where.workers)
        for outcome in outcomes:
            failed += outcome.error is not None
            bar.set_postfix(failed=failed, refresh=False)
            bar.update()
            yield outcome


def results(function: Callable[[Any], Any], jobs: Sequence[Any], where: Where,
            what: str = "job") -> list[Any]:
    """Every job's result, in the jobs' order; the first error is raised."""
    found: list[Any] = [None] * len(jobs)
    for outcome in run(function, jobs, where, what):
        if outcome.error is not None:
            raise outcome.error
        found[outcome.index] = outcome.result
    return found


def _here(function: Callable[[Any], Any], jobs: Sequence[Any]) -> Iterator[Outcome]:
    for index, job in enumerate(jobs):
        try:
            yield Outcome(index, function(job))
        except Exception as error:
            yield Outcome(index, error=error)


def _in_pool(function: Callable[[Any], Any], jobs: Sequence[Any], workers: int,
             ) -> Iterator[Outcome]:
    # Spawned `QuietProcess`es, not multiprocessing.Pool's daemons: a daemon cannot start
    # the processes a job may need (the controller's worker in a campaign run). One BLAS
    # thread each (unless the user chose): a job's matrices are 7 x 7, too small to gain
    # from threads, which beside a worker per core only compete with the workers.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    with ProcessPoolExecutor(workers, mp_context=SPAWN) as pool:
        futures = {pool.submit(function, job): index for index, job in enumerate(jobs)}
        try:
            for future in as_completed(futures):
                error = future.exception()
                yield Outcome(futures[future], None if error else future.result(), error)
        except (KeyboardInterrupt, GeneratorExit):
            _interrupt_children()
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def _interrupt_children() -> None:
    """SIGINT to this process's worker processes: each ends at once (`workers.SPAWN`)."""
    for child in multiprocessing.active_children():
        if child.pid is not None:
            try:
                os.kill(child.pid, signal.SIGINT)
            except ProcessLookupError:
                pass


def _on_cluster(function: Callable[[Any], Any], jobs: Sequence[Any], address: str,
                ) -> Iterator[Outcome]:
    from distributed import Client
    from distributed import as_completed as completed

    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except OSError as error:  # no scheduler there
        raise OSError(f"no Dask scheduler answers at {address}: {error}") from error
    with client:
        tqdm.write(f"on the Dask cluster at {address}: "
                   f"{len(client.scheduler_info()['workers'])} workers, dashboard "
                   f"{client.dashboard_link}", file=sys.stderr)
        futures = client.map(function, jobs, pure=False)
        index = {future.key: k for k, future in enumerate(futures)}
        try:
            for future in completed(futures):
                if future.status == "error":
                    yield Outcome(index[future.key], error=future.exception())
                else:
                    yield Outcome(index[future.key], future.result())
        except (KeyboardInterrupt, GeneratorExit):
            client.cancel(futures)
            raise
