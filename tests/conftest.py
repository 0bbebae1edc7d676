import os
import select
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def _shared_cache(uid: str) -> str:
    """The analysis cache of the parallel run ``uid`` (its controller removes it at the end)."""
    return os.path.join(tempfile.gettempdir(), f"infinitex-test-cache-{uid}")


# A private analysis cache per test run: tests never see a stale one. The
# workers of one parallel run (pytest-xdist) share it, so each analysis is made
# once per run (cache files are written atomically, so concurrent writers are safe).
_RUN = os.environ.get("PYTEST_XDIST_TESTRUNUID")
if _RUN:
    os.environ["INFINITEX_CACHE"] = _shared_cache(_RUN)
    os.makedirs(os.environ["INFINITEX_CACHE"], exist_ok=True)
else:
    os.environ["INFINITEX_CACHE"] = tempfile.mkdtemp(prefix="infinitex-test-cache-")
# No shader warm-up processes behind the tests' editors (tests/app/test_warmup.py runs one).
os.environ["INFINITEX_NO_WARMUP"] = "1"

from hypothesis import HealthCheck, settings  # noqa: E402

# Fuzzing profiles: "ci" (the default: a few hundred fixed cases, the same on
# every run) and "long" (pytest --hypothesis-profile=long: 10,000 random cases
# per target). bench/fuzz.py runs the same targets and reports figures.
_QUIET = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much,
          HealthCheck.large_base_example]
settings.register_profile("ci", max_examples=200, deadline=None, derandomize=True, database=None,
                          suppress_health_check=_QUIET, print_blob=True)
settings.register_profile("long", max_examples=10_000, deadline=None, database=None,
                          suppress_health_check=_QUIET, print_blob=True)
settings.load_profile("ci")

from infinitex.engine.analysis import AnalysisSettings, analyze  # noqa: E402
from infinitex.engine.exemplar import from_array, load_exemplar  # noqa: E402
from infinitex.engine.gpu import Gpu  # noqa: E402
from fast_set import LONG  # noqa: E402

ASSETS = os.path.join(ROOT, "infinitex", "assets")


@pytest.fixture(scope="session")
def gpu():
    return Gpu()


@pytest.fixture(scope="session")
def gravel():
    return load_exemplar(os.path.join(ASSETS, "gravel.png"))


def periodic_noise(m: int, channels: int = 3, seed: int = 1) -> np.ndarray:
    """A smooth random image that tiles exactly (filtered in the Fourier domain)."""
    rng = np.random.default_rng(seed)
    f = np.fft.fft2(rng.standard_normal((m, m, channels)), axes=(0, 1))
    fy, fx = np.fft.fftfreq(m)[:, None], np.fft.fftfreq(m)[None, :]
    f *= np.exp(-(fx ** 2 + fy ** 2) * (m / 6.0) ** 2)[:, :, None]
    img = np.real(np.fft.ifft2(f, axes=(0, 1)))
    img = (img - img.min()) / (img.max() - img.min())
    return img.astype(np.float32)


@pytest.fixture(scope="session")
def toroidal_ex():
    return from_array(periodic_noise(32), toroidal=True)


@pytest.fixture(scope="session")
def analyses(gravel, toroidal_ex):
    """Analyses shared by the synthesis tests, keyed by name."""
    return {
        "gravel-appearance": analyze(gravel, AnalysisSettings(model="appearance")),
        "gravel-color": analyze(gravel, AnalysisSettings(model="color")),
        "torus-appearance": analyze(toroidal_ex, AnalysisSettings(model="appearance")),
        "torus-color-k3": analyze(toroidal_ex, AnalysisSettings(model="color", k=3)),
    }


@pytest.fixture
def xdisplay():
    """A virtual X display of its own (Xvfb, 1280x800x24) for a test that runs the
    real editor: ":N", N chosen by the server (-displayfd), so tests in parallel
    processes never race for a number (xvfb-run -a can); started per test (0.2 s)
    so no key or button a driver left pressed reaches the next one."""
    if os.environ.get("INFINITEX_SKIP_GUI"):
        pytest.skip("INFINITEX_SKIP_GUI is set")
    exe = shutil.which("Xvfb")
    assert exe, "Xvfb is missing: run scripts/setup.sh (Debian packages xvfb, xauth)"
    r, w = os.pipe()
    proc = subprocess.Popen([exe, "-displayfd", str(w), "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(w)
    number = b""
    try:
        while not number.endswith(b"\n"):
            ready, _, _ = select.select([r], [], [], 30.0)
            chunk = os.read(r, 16) if ready else b""
            assert chunk, "Xvfb did not start"
            number += chunk
    finally:
        os.close(r)
    try:
        yield ":" + number.decode().strip()
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


# The GUI drivers (tests/app/test_editor.py) and their seconds, each alone on this
# 2-core machine (2026-12-07): what splits them into two chains of about equal
# length.
GUI_FILE = "tests/app/test_editor.py"
GUI_SECONDS = {
    "test_fast_input_is_never_lost": 152, "test_lattice_tool_driven_by_the_test_engine": 130,
    "test_everyday_use_driven_by_the_test_engine": 105, "test_large_photo_driven_by_the_test_engine": 69,
    "test_editor_driven_by_the_test_engine": 64, "test_a_dragged_slider_shows_texture_like_the_result": 50,
    "test_streamed_export_driven_by_the_test_engine": 38, "test_tile_set_dialog_driven_by_the_test_engine": 33,
}
GUI_CHAINS = 2


def gui_seconds(name: str) -> float:
    """A GUI driver's seconds alone (a new one counts as 20 s)."""
    return GUI_SECONDS.get(name.split("[")[0], 20)


def pytest_collection_modifyitems(config, items):
    """The tests of tests/fast_set.py marked slow; the long tests (GUI drivers,
    longest first, then those marked slow) first, so that in a parallel run they
    start at once instead of ending it alone."""
    for item in items:
        if item.nodeid in LONG or item.nodeid.split("[")[0] in LONG:
            item.add_marker(pytest.mark.slow)

    def rank(item):
        gui = item.get_closest_marker("gui")
        return (0 if gui else 1 if item.get_closest_marker("slow") else 2,
                -gui_seconds(item.name) if gui else 0)
    items.sort(key=rank)  # stable: the collection order within each rank


def pytest_xdist_make_scheduler(config, log):
    """A parallel run (scripts/test.sh: pytest-xdist, ``--dist load``) hands out
    work in units, in the suite's order, to whichever process is free: the GUI
    drivers in two chains of about equal length, each run by one process (two
    editors at a time beside the other tests: three at once on 2 cores slowed
    each one up to 6x, and one chain of them all ended the run alone), every
    other module whole (its fixtures made once). (xdist's own ``loadgroup``
    marks groups in a node id that pytest 9 no longer reads.)"""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class Units(LoadScopeScheduling):
        def __init__(self, config, log=None):
            super().__init__(config, log)
            config.option.loadscopereorder = False  # the suite's order, not the units' sizes
            self._chains = [0.0] * GUI_CHAINS
            self._units: dict[str, str] = {}

        def _split_scope(self, nodeid: str) -> str:
            unit = self._units.get(nodeid)
            if unit is None:  # (first asked in the collection's order: longest drivers first)
                path, _, name = nodeid.partition("::")
                unit = path
                if path == GUI_FILE:
                    c = self._chains.index(min(self._chains))
                    self._chains[c] += gui_seconds(name)
                    unit = f"gui{c}"
                self._units[nodeid] = unit
            return unit

    return Units(config, log)


# The suite's time budgets on 2 cores with llvmpipe (docs/testing.md): a run over
# its budget prints a warning (timing depends on the machine's load: it never fails).
BUDGET_S = {"": 720.0, "not gui and not slow": 180.0}
_T0 = pytest.StashKey[float]()


def pytest_configure(config):
    """The controller of a parallel run names the run (xdist passes the name to
    its workers) so it can remove the workers' shared cache at the end."""
    if not hasattr(config, "workerinput") and getattr(config.option, "numprocesses", None):
        if getattr(config.option, "testrunuid", None) is None:
            import uuid
            config.option.testrunuid = uuid.uuid4().hex


def pytest_unconfigure(config):
    """The run's analysis cache goes with the run (the controller's, or this
    process's own when not in parallel)."""
    if hasattr(config, "workerinput"):
        return
    shutil.rmtree(os.environ["INFINITEX_CACHE"], ignore_errors=True)
    uid = getattr(config.option, "testrunuid", None)
    if uid:
        shutil.rmtree(_shared_cache(uid), ignore_errors=True)


def pytest_sessionstart(session):
    session.config.stash[_T0] = time.monotonic()


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    whole = config.args_source == pytest.Config.ArgsSource.TESTPATHS and not config.getoption("keyword")
    budget = BUDGET_S.get(config.getoption("markexpr") or "")
    if hasattr(config, "workerinput") or not whole or budget is None or _T0 not in config.stash:
        return
    took = time.monotonic() - config.stash[_T0]
    if took > budget:
        terminalreporter.write_line(f"warning: the tests took {took:.0f} s, over their budget of {budget:.0f} s "
                                    "on 2 cores (docs/testing.md: where the time goes)", yellow=True)

