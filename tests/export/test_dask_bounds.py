"""The Dask connection of streamed exports (infinitex.export.workers): bounded
in time, and one line for every address that is not a Dask scheduler
(issue 29, items 12 and 16): a port that accepts and never speaks Dask, an
HTTP server, other transports (tls://, ucx://...), an empty --scheduler."""
import os
import re
import socket
import subprocess
import sys
import threading
import time

import pytest

from infinitex.export import ExportFailed
from infinitex.export.workers import check_scheduler_address, probe_scheduler

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GRAVEL = os.path.join(ROOT, "infinitex", "assets", "gravel.png")
HTTP_ANSWER = (b"HTTP/1.1 400 Bad Request\r\nContent-Type: text/plain\r\nContent-Length: 11\r\n"
               b"Connection: close\r\n\r\nbad request")


class Server:
    """A TCP server on 127.0.0.1 that accepts every connection and then says
    nothing ("silent") or answers like an HTTP server ("http")."""

    def __init__(self, mode: str):
        self.mode = mode
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.port = self.sock.getsockname()[1]
        self.conns: list[socket.socket] = []
        self.accepted = 0
        self.stop = False
        threading.Thread(target=self._serve, daemon=True).start()

    @property
    def address(self) -> str:
        return f"tcp://127.0.0.1:{self.port}"

    def _serve(self) -> None:
        while not self.stop:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.accepted += 1
            self.conns.append(conn)
            if self.mode == "http":
                try:
                    conn.settimeout(5)
                    conn.recv(65536)
                    conn.sendall(HTTP_ANSWER)
                except OSError:
                    pass

    def close(self) -> None:
        self.stop = True
        for c in self.conns:
            c.close()
        self.sock.close()


@pytest.fixture
def silent():
    s = Server("silent")
    yield s
    s.close()


@pytest.fixture
def http():
    s = Server("http")
    yield s
    s.close()


def export(tmp_path, *args, timeout=240):
    env = dict(os.environ, INFINITEX_CACHE=str(tmp_path / "cache"))
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, os.path.join(ROOT, "main.py"), "export", GRAVEL, "-o",
                        str(tmp_path / "t.png"), "--format", "tiles", "--rect", "0", "0", "64", "64", "--tile", "256",
                        *args], check=False, capture_output=True, text=True, timeout=timeout, env=env)
    return r, time.monotonic() - t0


def test_a_port_that_accepts_and_never_answers_fails_in_bounded_time(silent):
    t0 = time.monotonic()
    with pytest.raises(ExportFailed) as err:
        probe_scheduler(silent.address, timeout=2.0)
    elapsed = time.monotonic() - t0
    assert silent.accepted >= 1  # it did connect: the handshake is what never came
    assert elapsed < 30, elapsed   # bounded (2 s asked; generous for a loaded machine)
    msg = str(err.value)
    assert "did not answer within 2 s" in msg and silent.address in msg and "\n" not in msg


@pytest.mark.slow
def test_cli_export_against_a_silent_port_ends_with_one_line(silent, tmp_path):
    r, elapsed = export(tmp_path, "--scheduler", silent.address, "-q")
    assert r.returncode == 3, r.stderr[-2000:]
    assert r.stderr.startswith(f"error: The Dask scheduler at {silent.address} did not answer within 10 s")
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert elapsed < 200, elapsed  # 10 s of waiting, whatever the machine's load adds
    assert not any(n.startswith("t.") for n in os.listdir(tmp_path))  # refused before any tile


def test_an_http_answer_is_one_line_not_out_of_memory(http, tmp_path):
    with pytest.raises(ExportFailed) as err:
        probe_scheduler(http.address, timeout=5.0)
    assert "is not a Dask scheduler" in str(err.value)
    r, _ = export(tmp_path, "--scheduler", http.address, "-q")
    assert r.returncode == 3, r.stderr[-2000:]
    assert r.stderr.startswith(f"error: What answers at {http.address} is not a Dask scheduler")
    assert "memory" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


@pytest.mark.parametrize("address, words", [
    ("tls://127.0.0.1:8786", "uses tls://; only tcp://HOST:PORT addresses are supported"),
    ("ucx://127.0.0.1:8786", "uses ucx://; only tcp://HOST:PORT addresses are supported"),
    ("inproc://10.0.0.1/1/2", "uses inproc://"),
    ("ws://127.0.0.1:8786", "uses ws://"),
    ("", "--scheduler needs an address"),
    ("  ", "--scheduler needs an address"),
    ("tcp://127.0.0.1", "is not a Dask scheduler address"),
    ("127.0.0.1:99999", "is not a Dask scheduler address"),
    ("tcp://a b:1", "is not a Dask scheduler address"),
])
def test_other_transports_and_empty_addresses_are_refused_at_once(tmp_path, address, words):
    with pytest.raises(ValueError, match=re.escape(words)):
        check_scheduler_address(address)
    r, _ = export(tmp_path, "--scheduler", address, "-q", timeout=120)
    assert r.returncode == 2, r.stderr[-2000:]
    assert r.stderr.startswith("error: ") and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert not any(n.startswith("t.") for n in os.listdir(tmp_path))


def test_tcp_and_host_port_addresses_are_accepted():
    assert check_scheduler_address("local") == "local"
    assert check_scheduler_address("tcp://10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    assert check_scheduler_address("10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    assert check_scheduler_address(" TCP://node-3.cluster.example:08786 ") == "tcp://node-3.cluster.example:8786"
    assert check_scheduler_address("[::1]:8786") == "tcp://[::1]:8786"


def test_a_refused_port_says_it_cannot_be_reached():
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ExportFailed, match=f"Cannot reach the Dask scheduler at tcp://127.0.0.1:{port}"):
        probe_scheduler(f"127.0.0.1:{port}", timeout=2.0)


def test_a_real_scheduler_passes_the_probe():
    from distributed import LocalCluster
    with LocalCluster(n_workers=0, processes=False, protocol="tcp", host="127.0.0.1", dashboard_address=None) as cluster:
        assert probe_scheduler(cluster.scheduler_address, timeout=10.0) == cluster.scheduler_address
