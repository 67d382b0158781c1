"""Controller files: synthesis.save_controller / load_controller (.npz and .mat)."""
import os
import subprocess
import sys
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.io

import synthesis

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def controller():
    rng = np.random.default_rng(3)
    n = 5
    A = 0.3 * rng.standard_normal((n, n))
    return control.ss(A, rng.standard_normal((n, 2)), rng.standard_normal((1, n)), rng.standard_normal((1, 2)),
                      0.1, inputs=["r[0]", "y[0]"], outputs=["u[0]"], name="K")


@pytest.fixture(scope="module")
def design_controller():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(200)
    y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    return synthesis.hinf_design(synthesis.fit_predictor(u, y, 4), 1.0, 0.1).controller


def _same(a, b):
    for part in "ABCD":
        assert np.array_equal(np.asarray(getattr(a, part)), np.asarray(getattr(b, part))), part  # bit for bit
    assert a.dt == b.dt
    assert a.input_labels == b.input_labels and a.output_labels == b.output_labels
    assert a.state_labels == b.state_labels


@pytest.mark.parametrize("ending", [".npz", ".mat", ".NPZ"])
def test_round_trip(tmp_path, controller, design_controller, ending):
    for K in (controller, design_controller):
        path = synthesis.save_controller(tmp_path / f"K{ending}", K)
        back = synthesis.load_controller(path)
        assert isinstance(back, control.StateSpace)
        _same(back, K)
    assert synthesis.load_controller(synthesis.save_controller(tmp_path / f"K{ending}", controller)).name == "K"


@pytest.mark.parametrize("ending", [".npz", ".mat"])
def test_static_unspecified_dt_and_transfer_function(tmp_path, ending):
    G = control.ss(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((3, 0)), np.arange(6.0).reshape(3, 2), True)
    back = synthesis.load_controller(synthesis.save_controller(tmp_path / f"G{ending}", G))
    assert back.dt is True and back.nstates == 0
    assert np.array_equal(back.D, G.D)
    tf = control.tf([1.0, 0.5], [1.0, -0.2], 0.05)
    back = synthesis.load_controller(synthesis.save_controller(tmp_path / f"tf{ending}", tf))
    assert back.dt == 0.05
    z = np.exp(0.3j)
    assert complex(np.squeeze(back(z))) == pytest.approx(complex(np.squeeze(tf(z))), rel=1e-12)


def test_mat_file_is_readable_as_matlab_variables(tmp_path, controller):
    # second route: read the .mat file with scipy directly, as MATLAB would see it
    path = synthesis.save_controller(tmp_path / "K.mat", controller)
    raw = scipy.io.loadmat(path)
    assert np.array_equal(raw["A"], controller.A)
    assert raw["Ts"].item() == 0.1 and raw["dt"].item() == 0.1
    assert [str(x[0]) for x in raw["InputName"].ravel()] == ["r[0]", "y[0]"]
    raw_npz = np.load(synthesis.save_controller(tmp_path / "K.npz", controller))
    assert np.array_equal(raw_npz["B"], controller.B) and list(raw_npz["OutputName"]) == ["u[0]"]


def test_reload_in_a_new_process(tmp_path, design_controller):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for ending in (".npz", ".mat"):
        path = synthesis.save_controller(tmp_path / f"K{ending}", design_controller)
        code = ("import sys, numpy as np, synthesis; K = synthesis.load_controller(sys.argv[1]); "
                "np.savez(sys.argv[2], A=K.A, B=K.B, C=K.C, D=K.D, dt=K.dt, names=K.input_labels + K.output_labels)")
        out = tmp_path / f"out{ending}.npz"
        proc = subprocess.run([sys.executable, "-c", code, str(path), str(out)], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        got = np.load(out)
        for part in "ABCD":
            assert np.array_equal(got[part], getattr(design_controller, part))
        assert float(got["dt"]) == design_controller.dt
        assert list(got["names"]) == design_controller.input_labels + design_controller.output_labels


def test_errors_name_the_fix(tmp_path, controller):
    with pytest.raises(synthesis.ControllerFileError, match=r"\.npz.*\.mat"):
        synthesis.save_controller(tmp_path / "K.txt", controller)
    with pytest.raises(synthesis.ControllerFileError, match="ending"):
        synthesis.load_controller(tmp_path / "K")
    with pytest.raises(synthesis.InputTypeError, match="design.controller"):
        synthesis.save_controller(tmp_path / "K.npz", np.eye(2))
    with pytest.raises(FileNotFoundError):
        synthesis.load_controller(tmp_path / "absent.npz")
    np.savez(tmp_path / "partial.npz", A=np.eye(1), B=np.ones((1, 1)), C=np.ones((1, 1)))
    with pytest.raises(synthesis.ControllerFileError, match=r"no D, dt.*save_controller"):
        synthesis.load_controller(tmp_path / "partial.npz")
    scipy.io.savemat(tmp_path / "bad.mat", {"A": np.eye(2), "B": np.ones((3, 1)), "C": np.ones((1, 2)),
                                            "D": np.zeros((1, 1)), "dt": 0.1})
    with pytest.raises(synthesis.ControllerFileError, match="do not fit together"):
        synthesis.load_controller(tmp_path / "bad.mat")
    scipy.io.savemat(tmp_path / "nan.mat", {"A": np.full((1, 1), np.nan), "B": np.ones((1, 1)),
                                            "C": np.ones((1, 1)), "D": np.zeros((1, 1)), "Ts": 0.1})
    with pytest.raises(synthesis.ControllerFileError, match="finite"):
        synthesis.load_controller(tmp_path / "nan.mat")
    np.savez(tmp_path / "names.npz", A=np.eye(1), B=np.ones((1, 1)), C=np.ones((1, 1)), D=np.zeros((1, 1)),
             dt=0.1, InputName=np.array(["a", "b"]))
    with pytest.raises(synthesis.ControllerFileError, match="InputName has 2 name"):
        synthesis.load_controller(tmp_path / "names.npz")
    assert issubclass(synthesis.ControllerFileError, synthesis.DataError)


def test_swapped_arguments_and_unreadable_files_name_the_fix(tmp_path, controller):
    with pytest.raises(synthesis.InputTypeError, match=r"takes the file first.*save_controller\('K.npz', K\)"):
        synthesis.save_controller(controller, tmp_path / "K.npz")  # numpy's order is the file first
    (tmp_path / "junk.npz").write_bytes(b"not an archive")
    with pytest.raises(synthesis.ControllerFileError, match="cannot read .* as NPZ"):
        synthesis.load_controller(tmp_path / "junk.npz")
    (tmp_path / "junk.mat").write_bytes(bytes(200))
    with pytest.raises(synthesis.ControllerFileError, match="cannot read .* as a MATLAB file.*'-v7'"):
        synthesis.load_controller(tmp_path / "junk.mat")
    # MATLAB's v7.3 files are HDF5 behind a 128-byte header whose version field is 0x0200
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116) + bytes(8) + b"\x00\x02IM"
    (tmp_path / "v73.mat").write_bytes(header + b"\x89HDF\r\n\x1a\n" + bytes(256))
    with pytest.raises(synthesis.ControllerFileError, match=r"v7\.3 \(HDF5\).*'-v7'"):
        synthesis.load_controller(tmp_path / "v73.mat")


@pytest.mark.parametrize("ending", [".npz", ".mat"])
def test_a_system_with_nan_entries_is_not_written(tmp_path, ending):
    K = control.ss([[np.nan]], [[1.0, -1.0]], [[1.0]], [[0.0, 0.0]], 0.1)
    with pytest.raises(synthesis.ControllerFileError, match="A hold NaN or infinite"):  # load_controller refuses it
        synthesis.save_controller(tmp_path / f"K{ending}", K)
    assert not (tmp_path / f"K{ending}").exists()


@pytest.mark.parametrize("dt", ["x", "0.1", 0.1j])
def test_a_file_whose_dt_is_text_or_complex_is_refused(tmp_path, dt):
    """Text had raised numpy's bare ValueError (and '0.1' would have been parsed), complex had only warned."""
    np.savez(tmp_path / "K.npz", A=np.eye(1) * 0.5, B=np.ones((1, 1)), C=np.ones((1, 1)), D=np.zeros((1, 1)), dt=dt)
    with pytest.raises(synthesis.ControllerFileError, match="dt must be one number, a sample time >= 0"):
        synthesis.load_controller(tmp_path / "K.npz")


@pytest.mark.parametrize("ending", [".npz", ".mat"])
def test_complex_or_text_matrices_in_a_file_are_refused(tmp_path, ending):
    """A complex matrix had lost its imaginary part with only a ComplexWarning."""
    import warnings

    variables = {"A": np.eye(1) * 0.5j, "B": np.ones((1, 1)), "C": np.ones((1, 1)), "D": np.zeros((1, 1)), "dt": 0.1}
    if ending == ".npz":
        np.savez(tmp_path / "K.npz", **variables)
    else:
        scipy.io.savemat(tmp_path / "K.mat", variables)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(synthesis.ControllerFileError, match=r"K\.(npz|mat)': A is complex.*real part"):
            synthesis.load_controller(tmp_path / f"K{ending}")
    np.savez(tmp_path / "T.npz", A=np.array(["0.5"]), B=np.ones((1, 1)), C=np.ones((1, 1)), D=np.zeros((1, 1)),
             dt=0.1)
    with pytest.raises(synthesis.ControllerFileError, match="A must be real numbers, not text"):
        synthesis.load_controller(tmp_path / "T.npz")


def test_save_controller_refuses_a_path_or_name_of_another_type(tmp_path, controller):
    """save_controller(3, K) had raised pathlib's bare TypeError; name=3 or b'K' had been stored as its str()."""
    with pytest.raises(synthesis.InputTypeError, match=r"path must be a file name \(str or pathlib.Path\)"):
        synthesis.save_controller(3, controller)
    for name in (3, b"K"):
        with pytest.raises(synthesis.InputTypeError, match=r"name must be a string \(e.g. name='K'\)"):
            synthesis.save_controller(tmp_path / "K.mat", controller, name=name)
    # any string is a valid Name: it is stored as a value, not as a MATLAB variable name
    assert synthesis.load_controller(synthesis.save_controller(str(tmp_path / "K.mat"), controller,
                                                               name="my K[1]")).name == "my K[1]"


@pytest.mark.parametrize("fmt", synthesis.CONTROLLER_FORMATS)
@pytest.mark.parametrize("name", ["", " ", "K 2"])
def test_the_stored_name_round_trips_even_when_empty(tmp_path, controller, fmt, name):
    """MATLAB stores '' as an empty array; a .mat controller saved with name='' had come back under python-control's
    default name ('sys[3]') while the .npz one kept ''."""
    path = synthesis.save_controller(tmp_path / f"k{fmt}", controller, name=name)
    assert synthesis.load_controller(path).name == name
