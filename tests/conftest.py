"""Shared fixtures: synthetic scenes with exact geometry, and a runner for the real CLI."""
from __future__ import annotations

import contextlib
import importlib
import io
import os
import subprocess
import sys
import traceback
from pathlib import Path


def _avx2_without_avx512() -> bool:
    """Whether this CPU has AVX2 but no AVX-512 (Linux's /proc/cpuinfo; False where it cannot be read)."""
    try:
        flags = next(ln for ln in Path("/proc/cpuinfo").read_text().splitlines() if ln.startswith("flags")).split()
    except (OSError, StopIteration):
        return False
    return "avx2" in flags and "avx512f" not in flags


# oneDNN's AVX2 convolution kernels abort the process ("double free or corruption") in the backward pass of
# the suite's tiny networks (resfpn at width 4, channels-last, one thread) on AVX2-only CPUs (seen on an AMD
# EPYC; width 8 and up, and the AVX kernels, run): the suite, and every command it starts (they inherit
# the environment), then use oneDNN's AVX kernels. Set before torch is imported; a user's models are not
# touched (the shipped and benchmark models train and run on the default kernels on the same CPU).
if _avx2_without_avx512():
    os.environ.setdefault("DNNL_MAX_CPU_ISA", "AVX")

# Under pytest-xdist every core already runs a worker: a worker (and every command it starts) computing with
# one thread, not torch's and OpenCV's default of all cores, leaves no thread of an OpenMP pool waiting at a
# barrier for a core the other worker holds (vctrain/threads.py). Set before torch and cv2 are imported;
# a test that sets OMP_NUM_THREADS or --threads itself is unaffected.
XDIST_WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
if XDIST_WORKERS > 1:
    os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402

if XDIST_WORKERS > 1:
    cv2.setNumThreads(1)  # (OpenCV's pool: the same reason)
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from vcprep.camera import Camera, PRESETS  # noqa: E402
from vcprep.synthetic import RoadScene, render_road  # noqa: E402

BIN = Path(sys.executable).parent
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
# `vcprep warp` into the paper's virtual camera at 1/8 (688x350), each frame at its camera's average pose:
# the store of the tests of store mechanics (the default, the measured design: tests/test_user_route.py)
PAPER_STORE = ("--virtual", "virtual", "--scale", "0.125", "--within", "none")

cv2.setNumThreads(1)


def default_sigint() -> None:
    """A Ctrl-C test's ``preexec_fn``: the command starts with SIGINT at its default, as from a shell. A
    disposition of SIG_IGN survives exec, and the worker process that starts the command may hold one
    left by an earlier file's code (a command never then sees the Ctrl-C the test sends)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


# Scheduling only: `make test` runs the files on every core (pytest-xdist, --dist loadfile), handing
# out whole files in collection order. The files that take longest (they train models or kill and
# resume builds) go first so that no core is left alone with one of them at the end; the rest keep
# their alphabetical order. A file missing from this list still runs, after these.
LONGEST_FIRST = ["test_store_scale.py", "test_cli_store.py", "test_examples_pipeline.py",
                 "test_study_predict.py", "test_vctrain.py", "test_store_lock.py", "test_shell_use.py",
                 "test_ego.py", "test_road.py", "test_pipeline.py", "test_vanishing_point.py",
                 "test_fit_runs.py", "test_multi_camera.py", "test_completion.py", "test_export.py",
                 "test_docs.py", "test_store_sources.py", "test_datasets.py", "test_api.py", "test_adapt.py",
                 "test_store_stamp.py", "test_efficientnet.py", "test_study_roles.py", "test_study_loo.py"]


def pytest_configure(config):
    """The packages' bytecode, compiled once before the workers start. The suite starts ~650
    console scripts (and their pool workers), each a new interpreter; where bytecode is not cached
    (PYTHONDONTWRITEBYTECODE set, as on our machine) every one compiled vcprep or vctrain from
    source again, ~0.1 s of a 0.4 s start. compileall writes only what is missing or stale."""
    if hasattr(config, "workerinput"):  # an xdist worker: the controller has done it
        return
    import compileall

    root = Path(__file__).resolve().parent.parent
    for package in ("vcprep", "vctrain"):
        compileall.compile_dir(root / package, quiet=2)


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: order within a file kept


def run_cli(*args: str, prog: str = "vcprep", cwd: Path | None = None, process: bool = False) -> subprocess.CompletedProcess:
    """Run the command a user types: the installed console script ``prog``. ``vctrain`` runs in
    this process (:func:`_in_process`) unless ``process``: a new interpreter importing torch costs
    ~2 s, a third of the suite's time when every call paid it. So does any ``--help``: the page
    is Typer's rendering of the command's options, nothing a new interpreter changes (0.4 s each)."""
    if (prog == "vctrain" or "--help" in map(str, args)) and not process:
        return _in_process(prog, [str(a) for a in args], cwd)
    exe = BIN / prog
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=300)


def run_here(*args, prog: str = "vcprep", cwd: Path | None = None) -> subprocess.CompletedProcess:
    """``prog ARGS`` run by its console script's entry point in this process (:func:`_in_process`), for a
    command that starts no pool and catches no signal (a refusal, ``store show``/``info``/``verify -j 1``,
    ``vp``, ``camera show``, ``prior``): a new interpreter cost ~0.4 s a call. Builds, kills, locks, pools
    and pipes stay real processes (:func:`run_cli`)."""
    return _in_process(prog, [str(a) for a in args], cwd)


def _in_process(prog: str, args: list[str], cwd: Path | None) -> subprocess.CompletedProcess:
    """The console script's own entry point (``vctrain.cli:main``, what ``BIN/vctrain`` calls) in
    this process, as the interpreter would run it: its own argv, stdin empty, stdout and stderr
    captured apart, the exit status from SystemExit, an uncaught exception printed as a traceback
    on stderr with status 1."""
    main = importlib.import_module(f"{prog}.cli").main
    out, err = io.StringIO(), io.StringIO()
    argv, stdin, here = sys.argv, sys.stdin, os.getcwd()
    threads = _threads()  # a command's --threads (vctrain.threads) pins this process: set back after it
    code: int | str | None = 0
    try:
        sys.argv, sys.stdin = [str(BIN / prog), *args], io.StringIO("")
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main()
            except SystemExit as e:
                code = e.code
            except BaseException:  # noqa: BLE001 -- what the interpreter does with it
                traceback.print_exc()
                code = 1
    finally:
        sys.argv, sys.stdin = argv, stdin
        os.chdir(here)
        _threads(threads)
    if code is None:
        code = 0
    elif not isinstance(code, int):  # sys.exit("message"): the message on stderr, status 1
        err.write(f"{code}\n")
        code = 1
    return subprocess.CompletedProcess([str(BIN / prog), *args], code, out.getvalue(), err.getvalue())


def _threads(set_to: tuple[int, int] | None = None) -> tuple[int, int]:
    """(torch's, OpenCV's) thread counts; with ``set_to``, set them back to those first."""
    torch = sys.modules.get("torch")
    if set_to is not None:
        if torch is not None and set_to[0]:
            torch.set_num_threads(set_to[0])
        cv2.setNumThreads(set_to[1])
    return (torch.get_num_threads() if torch is not None else 0, cv2.getNumThreads())


def assert_one_error_line(proc: subprocess.CompletedProcess, *needles: str) -> None:
    assert proc.returncode != 0, proc.stdout
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("Error: "), proc.stderr
    assert "Traceback" not in proc.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.fixture(scope="session")
def camvid_half() -> Camera:
    """The camvid preset at the 480x360 size of the SegNet release."""
    return PRESETS["camvid"].for_image_size((480, 360))


def write_synthetic_dataset(folder: Path, cam: Camera, n: int = 3, poses=None, bonnet_rows: int = 0,
                            scene: RoadScene = RoadScene()) -> tuple[Path, Path]:
    """Render ``n`` frames to ``folder/images`` and CamVid-format labels (3 road, 0 else, 11 the
    bottom ``bonnet_rows`` rows) to ``folder/labels``."""
    img_dir, lab_dir = folder / "images", folder / "labels"
    img_dir.mkdir(parents=True, exist_ok=True)
    lab_dir.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        pan, tilt = poses[i] if poses else (None, None)
        img, lab = render_road(cam, RoadScene(offset=scene.offset + 0.3 * i, texture_seed=i), pan=pan, tilt=tilt,
                               supersample=1)
        ids = np.where(lab == 1, 3, 0).astype(np.uint8)
        if bonnet_rows:
            ids[-bonnet_rows:] = 11
        cv2.imwrite(str(img_dir / f"seq_{i:04d}.png"), img)
        cv2.imwrite(str(lab_dir / f"seq_{i:04d}.png"), ids)
    return img_dir, lab_dir


@pytest.fixture(scope="session")
def tiny_vc_model(tmp_path_factory) -> Path:
    """A width-8 virtual-camera network fitted for 3 epochs on 6 rendered CamVid-camera frames in the
    virtual camera at scale 0.02 (110x56), completed projectively (its quality does not matter: the
    tests that use it compare two paths through the same network)."""
    from vcprep.dataset import list_dataset
    from vcprep.io import write_png
    from vcprep.labels import get_label_format
    from vcprep.store import WarpSettings, warp_dataset
    from vctrain.training import TrainConfig, fit

    root = tmp_path_factory.mktemp("video_model")
    cam = PRESETS["camvid"].resized(0.1)
    (root / "src/images").mkdir(parents=True)
    (root / "src/labels").mkdir()
    for i in range(6):
        img, lab = render_road(cam, RoadScene(offset=-1.5 + 0.6 * i, texture_seed=i), pan=-4.0 + 1.6 * i)
        write_png(root / "src/images" / f"t_{i}.png", img)
        write_png(root / "src/labels" / f"t_{i}.png", lab)
    fmt = get_label_format("values:road=1;ignore=255")
    warp_dataset(list_dataset(root / "src/images", root / "src/labels", fmt), root / "store",
                 WarpSettings(cam, PRESETS["virtual"], 0.02, fmt, completion="projective", progress=False))
    fit(TrainConfig(stores=[str(root / "store")], out=str(root / "model.pt"), base_width=8, epochs=3, batch_size=3,
                    val_fraction=0, progress=False, device="cpu"))
    return root / "model.pt"
