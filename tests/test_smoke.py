import warnings

import numpy as np

import experiments
import synthesis
import unfalsify


def test_packages_import_and_fit_without_warnings():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(200)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:200] + 0.01 * rng.standard_normal(200)  # noisy: full-rank regressor
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pred = synthesis.fit_predictor(u, y, 5)
    assert pred.Lw.shape == (5, 10)
    assert pred.Lu.shape == (5, 5)
    assert pred.rank == pred.n_regressors
    assert abs(pred.Lu[1, 0] - 1.0) < 0.05 and abs(pred.Lu[2, 0] - 0.5) < 0.05  # Markov parameters (2.10)


def test_public_names_are_exported():
    for pkg in (synthesis, unfalsify, experiments):
        assert pkg.__all__, pkg.__name__
        for name in pkg.__all__:
            assert hasattr(pkg, name), f"{pkg.__name__}.{name}"


#: public modules that are namespaces of their own, not re-exported (scipy.signal.windows' way): the former
#: routes the benchmarks measure against, which must not crowd the package's API
NAMESPACES = {"baselines"}


def test_every_public_module_name_is_reexported():
    """What a synthesis module declares public in its __all__ is importable from the package (or, for a
    namespace module, from that module and not from the package)."""
    import importlib
    import pkgutil

    for info in pkgutil.iter_modules(synthesis.__path__):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"synthesis.{info.name}")
        if info.name in NAMESPACES:
            assert mod.__all__ and all(hasattr(mod, n) for n in mod.__all__), info.name
            assert not set(mod.__all__) & set(synthesis.__all__), info.name
            continue
        missing = sorted(set(getattr(mod, "__all__", ())) - set(synthesis.__all__))
        assert not missing, f"synthesis.{info.name}: {missing}"


def test_versions_come_from_the_installed_distribution():
    from importlib.metadata import version

    v = version("subspace-hinf")
    assert v and v[0].isdigit()
    for pkg in (synthesis, unfalsify, experiments):
        assert pkg.__version__ == v, pkg.__name__
