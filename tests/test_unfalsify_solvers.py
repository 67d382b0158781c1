"""The solver registry of ``unfalsify.solvers``: one contract for every solver, names that resolve, errors that
list the valid names, and the layout rules of issue 25 for synthesis/, unfalsify/ and experiments/: no import
circles, and no private name (module or attribute) imported, or read through an imported module, from outside the
module's own subpackage (its directory)."""
import ast
import pathlib
import pickle
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import synthesis as sy
import unfalsify as uf
from unfalsify import solvers

from _servo_arx import servo_arx_data  # tests/ helper

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _arx():
    u, y = servo_arx_data(30, 0)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    return uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * rms)


def _subspace(fixed):
    u, y = servo_arx_data(120, 1)
    i = 4
    pred = sy.fit_predictor(u, y, i)
    n = 2 * i + 20 - 1
    A, _, Yf = uf.subspace_data(u[:n], y[:n], i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T  # the window's own least squares: δ > 0 with L free too
    sigma = 0.5 * np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size)
    return uf.SubspaceProblem.from_data(u[:n], y[:n], i, sigma, predictor=pred if fixed else None)


def test_backend_and_method_resolve_to_registered_solvers():
    assert uf.SOLVERS is solvers.SOLVERS
    assert set(solvers.SOLVERS) == {"cvxpy", "arx_barrier", "arx_pd", "bracket", "column_barrier", "column_pd",
                                   "block_barrier", "split"}
    assert solvers.resolve("arx", "cvxpy") == solvers.resolve("subspace", "cvxpy") == "cvxpy"
    assert solvers.resolve("arx", "structured") == "arx_barrier"
    assert solvers.resolve("arx", "structured", "bracket") == "bracket"
    assert solvers.resolve("arx", "structured", "primal_dual") == "arx_pd"
    assert solvers.resolve("subspace", "structured") == "column_barrier"
    assert solvers.resolve("subspace", "structured", "primal_dual") == "column_pd"
    for program, name in [(p, n) for n, ps in solvers.PROGRAMS.items() for p in ps]:
        assert name in solvers.SOLVERS and program in ("arx", "subspace")


def test_unknown_names_raise_our_value_error_listing_the_valid_ones():
    with pytest.raises(uf.UnknownSolverError, match="'cvxpy', 'structured'") as err:
        solvers.resolve("arx", "mosek")
    assert isinstance(err.value, ValueError)
    with pytest.raises(uf.UnknownSolverError, match="'barrier', 'bracket'"):
        solvers.resolve("arx", "structured", "admm")
    with pytest.raises(uf.UnknownSolverError, match="'barrier'"):
        solvers.resolve("subspace", "structured", "bracket")
    with pytest.raises(uf.UnknownSolverError, match="'arx_barrier'"):
        solvers.run("nope", _arx())
    with pytest.raises(uf.UnknownSolverError, match="'cvxpy', 'column_barrier', 'column_pd', 'block_barrier', 'split'"):
        solvers.run("arx_barrier", _subspace(fixed=True))


@pytest.mark.parametrize("options, match", [
    (dict(tol=-1.0), "tol must be a relative gap in \\(0, 1\\)"), (dict(tol=0.0), "tol must"), (dict(tol=1.5), "tol must"),
    (dict(tol="1e-6"), "tol must"), (dict(tol=True), "tol must"),
    (dict(time_limit=-1.0), "time_limit must be None or a number"), (dict(time_limit="60"), "time_limit must"),
])
def test_stopping_rules_are_checked_before_a_solve(options, match):
    # a negative tolerance can never be met: the solve had ended 'failed' without saying why
    for name, problem in (("arx_barrier", _arx()), ("column_barrier", _subspace(fixed=True))):
        with pytest.raises(sy.DataError, match=match):
            solvers.run(name, problem, progress=False, **options)


@pytest.mark.parametrize("name, problem, options", [
    ("cvxpy", "arx", {}),
    ("arx_barrier", "arx", dict(progress=False)),
    ("arx_pd", "arx", dict(progress=False)),
    ("bracket", "arx", dict(progress=False)),
    ("cvxpy", "subspace", {}),
    ("column_barrier", "subspace", dict(progress=False)),
    ("column_pd", "subspace", dict(progress=False)),
    ("split", "subspace-fixed", dict(executor=None)),
])
def test_every_solver_meets_the_contract(name, problem, options):
    P = {"arx": _arx, "subspace": lambda: _subspace(False), "subspace-fixed": lambda: _subspace(True)}[problem]()
    out = solvers.run(name, P, **options)
    assert isinstance(out, uf.SolverOutput) and isinstance(out.status, uf.SolverStatus)
    assert out.status in (uf.SolverStatus.OPTIMAL, uf.SolverStatus.BRACKET)
    assert out.bracketed == (name in ("arx_barrier", "arx_pd", "bracket", "column_barrier", "column_pd"))
    up, noise = P.evaluate_primal(out.impulses, out.params)  # data units: the primal point is feasible
    assert noise <= P.sigma * np.sqrt(P.n_noise) * (1 + 1e-6)
    assert up <= out.delta * (1 + 1e-6)
    assert 0 < P.evaluate_dual(out.dual_v, out.dual_W) <= up * (1 + 1e-6)
    back = pickle.loads(pickle.dumps(out))
    assert back.status is out.status and back.delta == out.delta and back.problem is None


def test_split_with_an_executor_equals_the_serial_split():
    P = _subspace(True)
    serial = solvers.run("split", P)
    with ThreadPoolExecutor(2) as ex:
        pooled = solvers.run("split", P, executor=ex)
    assert pooled.delta == serial.delta


def test_split_outer_problem_closes_where_false_position_stalled():
    """A noise ball far inside the residual (σ = 0.1 × the fixed predictor's residual rms): g(δ) is flat above δ*, and
    false position from the lower end had found only upper ends (measured: 30 of 30 rounds on this record).  The
    bracket closes within 15 rounds and its δ is the structured barrier's (another method on the same program)."""
    from unfalsify.solvers.split import split_solve

    rng = np.random.default_rng(2)
    u = rng.choice([-1.0, 1.0], 80)
    y = np.convolve(u, [0.0, 1.0, 0.5, 0.25])[:80] + 0.1 * rng.standard_normal(80)
    pred = sy.fit_predictor(u, y, 4)
    A, Uf, Yf = uf.subspace_data(u, y, 4)
    B = Yf - np.hstack([pred.Lw, pred.Lu]) @ A
    sigma = 0.1 * np.linalg.norm(B) / np.sqrt(B.size)
    out = split_solve(Uf, B, sigma * np.sqrt(B.size), max_rounds=15)
    ref = uf.subspace_unfalsify(u, y, 4, sigma, predictor=pred, backend="structured", tol=1e-8, progress=False)
    assert out["status"] == "optimal" and out["lower"] <= out["delta"]
    assert out["delta"] == pytest.approx(ref.delta, rel=1e-6)


@pytest.mark.parametrize("kw, match", [
    (dict(max_rounds=0), "max_rounds must be an integer ≥ 1"),  # had raised UnboundLocalError
    (dict(max_rounds=2.5), "max_rounds must be an integer ≥ 1"),
    (dict(rho="x"), r"rho \(the noise budget σ√N\) must be a real number > 0"),  # had raised TypeError
    (dict(rho=float("nan")), r"rho .*must be a finite number > 0"),
    (dict(nan=True), "U and B contain NaN or infinite values"),  # had raised scipy's ValueError
    (dict(executor="x"), r"executor must be a concurrent.futures.Executor"),  # had raised AttributeError
    (dict(block_size=0), "block_size must be an integer ≥ 1"),
])
def test_split_solve_refuses_bad_arguments_with_the_fix(kw, match):
    from unfalsify.solvers.split import split_solve

    u, y = servo_arx_data(40, 3)
    pred = sy.fit_predictor(u, y, 2)
    A, Uf, Yf = uf.subspace_data(u[:7], y[:7], 2)
    B = Yf - np.hstack([pred.Lw, pred.Lu]) @ A
    if kw.pop("nan", False):
        B[0, 0] = np.nan
    args = dict(rho=0.1 * np.linalg.norm(B)) | kw
    with pytest.raises(sy.DataError, match=match):
        split_solve(Uf, B, **args)
    # one round is a valid bound: a bracket, its upper end feasible
    out = split_solve(Uf, np.nan_to_num(B), 0.1 * np.linalg.norm(np.nan_to_num(B)), max_rounds=1)
    assert out["rounds"] == 1 and out["lower"] <= out["delta"]


def test_an_executor_without_submit_is_refused_through_subspace_unfalsify():
    u, y = servo_arx_data(40, 3)
    pred = sy.fit_predictor(u, y, 2)
    with pytest.raises(sy.DataError, match=r"executor must be a concurrent.futures.Executor.*got 'x'"):
        uf.subspace_unfalsify(u[:7], y[:7], 2, 0.02, predictor=pred, executor="x")


def test_status_strings_of_results_are_the_shared_enum_values():
    u, y = servo_arx_data(30, 0)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", method="bracket", progress=False)
    assert type(r.status) is str and uf.SolverStatus(r.status) is uf.SolverStatus.BRACKET


def _imports(path):
    pkg = list(path.relative_to(ROOT).with_suffix("").parts[:-1])
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            base = pkg[: len(pkg) - node.level + 1] if node.level else []
            module = base + (node.module.split(".") if node.module else [])
            for alias in node.names:
                yield pkg, module, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield pkg, alias.name.split("."), None


@pytest.mark.parametrize("package", ["synthesis", "unfalsify", "experiments"])
def test_no_private_names_across_packages(package):
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for pkg, module, name in _imports(path):
            if module[0] not in ("synthesis", "unfalsify", "experiments"):
                continue
            home = module if name is None or module == pkg else module[:-1]
            private = [p for p in module[1:] if p.startswith("_")] + ([name] if name and name.startswith("_")
                                                                        and not name.startswith("__") else [])
            if private and home != pkg:
                bad.append((str(path.relative_to(ROOT)), ".".join(module), name))
        bad += [(str(path.relative_to(ROOT)), ".".join(owner), attr) for owner, attr in _private_attributes(path)]
    assert not bad, f"private names imported from another (sub)package: {bad}"


def _subpackage(dotted):
    """The directory of the longest prefix of ``dotted`` that is a module or package of the project."""
    for k in range(len(dotted), 0, -1):
        where = ROOT / pathlib.Path(*dotted[:k])
        if (where / "__init__.py").exists():
            return dotted[:k]
        if where.with_suffix(".py").exists():
            return dotted[: k - 1]
    return None


def _private_attributes(path):
    """``(owner, name)`` of each ``alias._name`` read through a project module bound by an import (``import
    synthesis as sy; sy.hinf._x``, ``from ..lab import simulate; simulate._x``) whose owner lies in another
    subpackage: a private name reached without importing it by name."""
    pkg = list(path.relative_to(ROOT).with_suffix("").parts[:-1])
    tree = ast.parse(path.read_text(), str(path))
    bound = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = pkg[: len(pkg) - node.level + 1] if node.level else []
            module = base + (node.module.split(".") if node.module else [])
            for alias in node.names:
                cand = module + [alias.name]
                where = ROOT / pathlib.Path(*cand)
                if (where / "__init__.py").exists() or where.with_suffix(".py").exists():
                    bound[alias.asname or alias.name] = cand
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                bound[alias.asname] = parts if alias.asname else None
                if not alias.asname:
                    bound[parts[0]] = parts[:1]
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")):
            continue
        chain, value = [], node.value
        while isinstance(value, ast.Attribute):
            chain.insert(0, value.attr)
            value = value.value
        if isinstance(value, ast.Name) and bound.get(value.id) and bound[value.id][0] in (
                "synthesis", "unfalsify", "experiments"):
            owner = bound[value.id] + chain
            if _subpackage(owner) != pkg:
                yield owner, node.attr


@pytest.mark.parametrize("package", ["synthesis", "unfalsify", "experiments"])
def test_no_import_circles(package):
    edges = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        me = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        targets = edges.setdefault(me, set())
        for _, module, name in _imports(path):
            for cand in (".".join(module + [name]) if name else None, ".".join(module)):
                if cand and (ROOT / pathlib.Path(*cand.split("."))).with_suffix(".py").exists():
                    targets.add(cand)
                    break
    # packages' __init__ re-export their modules: an edge into a package face is not a circle of modules
    edges = {m: {t for t in ts if not (ROOT / pathlib.Path(*t.split(".")) / "__init__.py").exists()}
             for m, ts in edges.items()}
    state = {}

    def visit(m, stack):
        state[m] = "open"
        for t in edges.get(m, ()):
            if state.get(t) == "open":
                pytest.fail(f"import circle: {' -> '.join(stack[stack.index(t):] + [t])}")
            if t not in state:
                visit(t, stack + [t])
        state[m] = "done"

    for m in sorted(edges):
        if m not in state:
            visit(m, [m])


def test_arx_barrier_counts_its_trial_factorisations():
    """ARX results carry the solver's counts: every Newton step factorises K at least once (its accepted point),
    the line searches and path steps more; cvxpy keeps none (only the excess of a point moved into the noise
    ball, ``into_ball``, when its point lay outside)."""
    rng = np.random.default_rng(8)
    u = rng.standard_normal(120)
    y = np.convolve(u, [0.0, 0.8, 0.3])[:120] + 0.05 * rng.standard_normal(120)
    res = uf.arx_unfalsify(u, y, 1, 2, 0.03, backend="structured", progress=False)
    stats = res.solver_stats
    assert stats["newton"] >= 1 and stats["trials"] >= stats["newton"] + 1 and stats["outer"] >= 1
    assert set(uf.arx_unfalsify(u[:40], y[:40], 1, 2, 0.03, solver="CLARABEL").solver_stats) <= {"into_ball"}
