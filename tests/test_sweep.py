"""Monte Carlo sweep and the column split of (7.5) on executors, against a real Dask LocalCluster.

Two worker processes on loopback; every workload here is tiny (seconds).  The distributed tests skip
only where dask.distributed is not installed (it is part of the ``test`` extra).
"""
from __future__ import annotations

import concurrent.futures as cf
import json
import math
import os
import socket
import time

import numpy as np
import pytest

import synthesis
import unfalsify as uf
from experiments import cli
from experiments.studies import sweep as sw
from experiments.lab.plants import servo
from experiments.lab.signals import prbs
from experiments.lab.simulate import collect_data
from synthesis._validation import DataError

try:
    import distributed
except ImportError:  # pragma: no cover - the test extra installs it
    distributed = None

needs_dask = pytest.mark.skipif(distributed is None, reason="dask.distributed not installed: pip install -e '.[distributed]'")

CASES = [sw.Case("servo", 0, 5, 20, 0.5), sw.Case("third_order", 1, 5, 20, 0.8)]


@pytest.fixture(scope="module")
def client():
    if distributed is None:
        pytest.skip("dask.distributed not installed: pip install -e '.[distributed]'")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                       dashboard_address="127.0.0.1:0", env=dict(sw.WORKER_ENV))
    c = distributed.Client(cluster, set_as_default=False)
    yield c
    c.close()
    cluster.close()


def _close(a, b, rtol=1e-9):
    """Recursive equality, floats to ``rtol`` (BLAS thread counts may differ between processes)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], rtol) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_close(x, y, rtol) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return a == b or abs(a - b) <= rtol * max(abs(a), abs(b))
    return a == b


# --------------------------------------------------------------------------- sweep
@pytest.mark.slow
@needs_dask
def test_sweep_on_cluster_equals_serial(client, tmp_path):
    serial = [sw.case_task(c) for c in CASES]
    with client.get_executor() as ex:
        s = sw.run_sweep(CASES, ex, tmp_path, executor_info={"kind": "test"}, progress=False)
    assert (s["done"], s["failed"], s["missing"]) == (2, 0, 0)
    assert _close(sw.strip_timing(s["cases"]), sw.strip_timing(serial))
    data = json.loads((tmp_path / "sweep.json").read_text())
    assert [c["plant"] for c in data["cases"]] == ["servo", "third_order"]
    for c in data["cases"]:
        assert {"plant", "seed", "i", "j", "sigma", "delta", "certified"} <= c.keys()


@pytest.mark.slow
@needs_dask
def test_failing_case_is_reported_and_sweep_goes_on(client, tmp_path):
    cases = [sw.Case("no_such_plant", 0, 5, 20, 0.5), CASES[0]]
    with client.get_executor() as ex:
        s = sw.run_sweep(cases, ex, tmp_path, progress=False)
    assert (s["done"], s["failed"]) == (1, 1)
    bad = s["cases"][0]
    assert "unknown plant 'no_such_plant'" in bad["error"]
    assert "no_such_plant" in (tmp_path / "sweep.md").read_text()
    assert "1 done, 1 failed" in sw.summary_line(s)


def _die_on_seed_1(case):
    if case.seed == 1:
        os._exit(3)  # the worker process disappears mid-sweep
    return {"plant": case.plant, "seed": case.seed, "i": case.i, "j": case.j, "sigma_ratio": case.sigma_ratio,
            "certified": False}


@pytest.mark.slow
def test_lost_worker_cases_reported_failed(tmp_path):
    cases = [sw.Case("servo", s, 5, 20, 0.5) for s in range(3)]
    import multiprocessing

    with cf.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as ex:
        s = sw.run_sweep(cases, ex, tmp_path, task=_die_on_seed_1, progress=False)
    assert s["missing"] == 0 and len(s["cases"]) == 3  # never silently missing
    assert s["failed"] >= 1
    assert any("worker lost" in c.get("error", "") for c in s["cases"])


def test_resume_skips_finished_cases(tmp_path):
    calls = []

    def task(c):
        calls.append(c.key())
        return {"plant": c.plant, "seed": c.seed, "i": c.i, "j": c.j, "sigma_ratio": c.sigma_ratio,
                "certified": True, "delta": 0.1}

    cases = [sw.Case("servo", s, 5, 20, 0.5) for s in range(3)]
    with cf.ThreadPoolExecutor(1) as ex:
        sw.run_sweep(cases[:2], ex, tmp_path, task=task, progress=False)
        finished = sw.load_finished(tmp_path / "sweep.json")
        assert set(finished) == {c.key() for c in cases[:2]}
        calls.clear()
        s = sw.run_sweep(cases, ex, tmp_path, task=task, finished=finished, progress=False)
    assert calls == [cases[2].key()]
    assert s["done"] == 3 and s["certified"] == 3


@pytest.mark.slow
def test_unreachable_scheduler_errors_in_time():
    pytest.importorskip("distributed", reason="dask.distributed not installed: pip install -e '.[distributed]'")
    with socket.socket() as sock:  # a closed loopback port
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    t0 = time.perf_counter()
    with pytest.raises(DataError, match=f"127.0.0.1:{port}"):
        with sw.make_executor(scheduler=address, timeout=2.0):
            pass
    assert time.perf_counter() - t0 < 20.0


def test_scheduler_without_distributed_names_the_extra(monkeypatch):
    monkeypatch.setattr(sw, "_have_distributed", lambda: False)
    with pytest.raises(DataError, match=r"\.\[distributed\]"):
        with sw.make_executor(scheduler="tcp://127.0.0.1:1"):
            pass


def test_bad_workers_rejected():
    with pytest.raises(DataError, match="--workers"):
        with sw.make_executor(workers=0):
            pass


def test_cli_sweep_options_only_on_sweep():
    p = cli._parser()
    a = p.parse_args(["sweep", "--workers", "2", "--resume", "--scheduler", "tcp://127.0.0.1:8786"])
    assert (a.workers, a.resume, a.scheduler, a.timeout) == (2, True, "tcp://127.0.0.1:8786", 30.0)
    with pytest.raises(SystemExit):
        p.parse_args(["demo", "--workers", "2"])
    assert cli.Options().extra == {}


def test_catalogue_has_five_plants_of_different_character():
    names = {c.plant for c in sw.sweep_cases(sw.SweepConfig())}
    assert {"servo", "third_order", "resonant", "nonminimum_phase", "three_disk_y1"} <= names
    q = sw.SweepConfig.quick()
    assert len(q.plants) >= 2 and len(q.seeds) >= 2


# --------------------------------------------------------------------------- column split of (7.5)
def _data(i, j):
    n = 2 * i + j - 1
    d = collect_data(servo(), prbs(max(n, 200), seed=0), process_noise=0.05, sensor_noise=0.05, seed=100)
    pred = synthesis.fit_predictor(d.u[:, 0], d.y[:, 0], i)
    return d.u[:n, 0], d.y[:n, 0], pred


@pytest.fixture(scope="module")
def small_problem():
    u, y, pred = _data(4, 16)
    return u, y, pred, uf.subspace_unfalsify(u, y, 4, 0.05, predictor=pred)


def _check_split(res, ref):
    assert res.backend == "split"
    assert abs(res.delta - ref.delta) <= 1e-6 * ref.delta
    cert = res.certificate
    assert isinstance(cert, uf.Certificate)
    assert cert.ok() and cert.verify()
    assert cert.lower_bound <= cert.upper_bound <= res.delta * (1 + 1e-12)
    assert cert.relative_gap < 1e-5


@pytest.mark.slow
def test_split_in_threads_equals_serial(small_problem):
    u, y, pred, ref = small_problem
    with cf.ThreadPoolExecutor(2) as ex:
        _check_split(uf.subspace_unfalsify(u, y, 4, 0.05, predictor=pred, executor=ex), ref)


@pytest.mark.slow
@needs_dask
def test_split_on_cluster_equals_serial(client, small_problem):
    u, y, pred, ref = small_problem
    with client.get_executor() as ex:
        res = uf.subspace_unfalsify(u, y, 4, 0.05, predictor=pred, executor=ex)
    _check_split(res, ref)
    # the same columns give the same numbers whatever the executor
    with cf.ThreadPoolExecutor(1) as ex:
        res1 = uf.subspace_unfalsify(u, y, 4, 0.05, predictor=pred, executor=ex)
    assert res1.delta == res.delta and np.array_equal(res1.impulses, res.impulses)


def test_split_needs_a_fixed_predictor(small_problem):
    u, y, _, _ = small_problem
    with cf.ThreadPoolExecutor(1) as ex, pytest.raises(DataError, match="predictor"):
        uf.subspace_unfalsify(u, y, 4, 0.05, executor=ex)


def test_split_column_slope_matches_finite_difference():
    from unfalsify.solvers.split import solve_column

    rng = np.random.default_rng(0)
    u, b = np.sign(rng.standard_normal(6)), rng.standard_normal(6)
    a, c = solve_column(u, b, 0.5, 1e-12), solve_column(u, b, 0.5 + 1e-6, 1e-12)
    assert c["f"] <= a["f"]  # non-increasing in δ
    assert abs((c["f"] - a["f"]) / 1e-6 - a["df"]) <= 1e-4 * abs(a["df"])


@pytest.mark.parametrize("dask", [False, True])
def test_local_executors_run_workers_with_one_blas_thread(dask, monkeypatch):
    if dask and distributed is None:
        pytest.skip("dask.distributed not installed: pip install -e '.[distributed]'")
    if not dask:
        monkeypatch.setattr(sw, "_have_distributed", lambda: False)
    with sw.make_executor(1) as (ex, info):
        assert info["kind"] == ("dask-local" if dask else "process-pool")
        assert ex.submit(os.getenv, "OPENBLAS_NUM_THREADS").result() == "1"
    assert os.environ.get("OPENBLAS_NUM_THREADS") == ("1" if os.environ.get("OPENBLAS_NUM_THREADS") else None)
