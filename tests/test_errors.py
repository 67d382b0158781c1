"""The "Errors you may see" table of docs/ERRORS.md, row by row: each bad input raises the stated error."""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import control
import numpy as np
import pytest

import synthesis as sy
import unfalsify as uf
from synthesis.weights import WeightError

ERRORS_DOC = Path(__file__).resolve().parents[1] / "docs" / "ERRORS.md"


def _rows() -> list[tuple[str, str, str]]:
    text = ERRORS_DOC.read_text().split("# Errors you may see", 1)[1].split("\n#", 1)[0]
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if len(cells) == 3 and cells[0].startswith("`"):
            rows.append(tuple(c.strip("`") for c in cells))
    return rows


ROWS = _rows()


def test_table_is_there():
    assert len(ROWS) >= 20


@pytest.fixture(scope="module")
def namespace():
    rng = np.random.default_rng(0)
    n = 300
    u = rng.standard_normal(n)
    y = np.convolve(u, [0.0, 0.5, 0.3, 0.1])[:n] + 0.02 * rng.standard_normal(n)
    pred = sy.fit_predictor(u, y, 5)
    W = control.tf([1, 0.2], [1, -0.5], 1.0)
    K = sy.hinf_design(pred, W, W).controller
    return {"np": np, "control": control, "sy": sy, "uf": uf, "u": u, "y": y, "pred": pred, "W": W, "K": K}


ERRORS = {"DataError": sy.DataError, "WeightError": WeightError, "InputTypeError": sy.InputTypeError,
          "InfeasibleGammaError": sy.InfeasibleGammaError}


@pytest.mark.parametrize("call, error, message", ROWS, ids=[r[0] for r in ROWS])
def test_bad_input_raises_our_error(call, error, message, namespace):
    exc_type = ERRORS[error]
    assert issubclass(exc_type, ValueError)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(exc_type, match=re.escape(message)) as info:
            eval(call, dict(namespace))
    assert type(info.value).__module__.split(".")[0] in ("synthesis", "unfalsify"), "raised by the toolkit"


def test_input_type_error_is_also_a_type_error():
    with pytest.raises(TypeError):
        sy.hinf_norm("G")
