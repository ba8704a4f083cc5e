"""The rerun web viewer, served on this machine only: ``rerun --serve-web`` bound to
127.0.0.1, for ``rerun_bridge``'s ``serve_web``."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import time
from pathlib import Path

LOCALHOST = "127.0.0.1"  # servers listen on loopback only: nothing is exposed to the network
SERVER_START_TIMEOUT = 10.0  # [s] wall time for `rerun --serve-web` to open its ports
SERVER_STOP_TIMEOUT = 3.0  # [s] wall time between SIGTERM and SIGKILL of the server
PR_SET_PDEATHSIG = 1  # linux/prctl.h


def rerun_executable() -> str:
    """Path of the ``rerun`` binary shipped with rerun-sdk (not the Python wrapper script: a
    signal to the wrapper would not reach the server it starts)."""
    import shutil

    with contextlib.suppress(ImportError):
        import rerun_cli

        packaged = Path(rerun_cli.__file__).with_name("rerun")
        if packaged.is_file():
            return str(packaged)
    exe = shutil.which("rerun")
    if exe is None:
        raise FileNotFoundError("the rerun binary (pip install rerun-sdk)")
    return exe


def _die_with_parent() -> None:  # runs in the child between fork and exec
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


class WebViewerServer:
    """A ``rerun --serve-web`` child process bound to 127.0.0.1: a gRPC proxy at
    :attr:`grpc_url` (log to it with a ``GrpcSink``) and the web viewer at :attr:`web_url`.

    :meth:`stop` ends it by its PID (and it dies with its parent process). It keeps what was
    logged in memory, up to ``memory_limit``, for viewers that connect late.
    """

    def __init__(self, grpc_port: int, web_port: int, memory_limit: str = "25%") -> None:
        import socket

        self.grpc_port, self.web_port = grpc_port, web_port
        for port in (grpc_port, web_port):  # fail here, with the port named, not in the child
            with socket.socket() as sock:
                if sock.connect_ex((LOCALHOST, port)) == 0:
                    raise OSError(f"port {port} on {LOCALHOST} is already in use")
        # Its own session: a Ctrl-C meant for the caller must not end the server before the
        # caller has flushed to it; the kernel ends it if the caller dies (PR_SET_PDEATHSIG).
        self.proc = subprocess.Popen(
            [rerun_executable(), "--serve-web", "--bind", LOCALHOST, "--port", str(grpc_port),
             "--web-viewer-port", str(web_port), "--server-memory-limit", memory_limit],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True, preexec_fn=_die_with_parent)
        deadline = time.monotonic() + SERVER_START_TIMEOUT
        while not all(self._listening(p) for p in (grpc_port, web_port)):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise OSError(f"rerun --serve-web did not open ports {grpc_port} and "
                              f"{web_port} on {LOCALHOST} within {SERVER_START_TIMEOUT:g} s")
            time.sleep(0.05)

    @staticmethod
    def _listening(port: int) -> bool:
        import socket

        with socket.socket() as sock:
            return sock.connect_ex((LOCALHOST, port)) == 0

    @property
    def grpc_url(self) -> str:
        return grpc_proxy_url(self.grpc_port)

    @property
    def web_url(self) -> str:
        return web_viewer_url(self.web_port, self.grpc_port)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=SERVER_STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def grpc_proxy_url(grpc_port: int) -> str:
    return f"rerun+http://{LOCALHOST}:{grpc_port}/proxy"


def web_viewer_url(web_port: int, grpc_port: int) -> str:
    """The address a browser opens: the web viewer, pointed at the gRPC proxy."""
    from urllib.parse import quote

    return f"http://{LOCALHOST}:{web_port}/?url={quote(grpc_proxy_url(grpc_port), safe='')}"


def free_ports(count: int) -> list[int]:
    """``count`` distinct TCP ports free on 127.0.0.1 right now (the kernel's choice), so that a
    second run on the machine never collides with the first one's viewer."""
    import socket

    socks = []
    try:
        for _ in range(count):
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.bind((LOCALHOST, 0))
            socks.append(sock)
        return [s.getsockname()[1] for s in socks]
    finally:
        for sock in socks:
            sock.close()
