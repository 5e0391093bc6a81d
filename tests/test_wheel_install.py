"""A non-editable install (a built wheel in a fresh virtual environment) serves the map page.

The page lives in gcs/web/ and ships as package data; nothing may find it relative to the source tree. The
fresh environment borrows the test environment's third-party packages through a path entry (not its .pth
files, so the editable install of this repository is not visible there), and runs from a directory outside
the checkout, so only the wheel's copy of our packages can be imported.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import sysconfig
import time
import urllib.request
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = [pytest.mark.slow, pytest.mark.integration, pytest.mark.timeout(900)]  # the first one builds the wheel


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _get(url: str) -> tuple[int, str, bytes]:
    with urllib.request.urlopen(url, timeout=5) as response:
        return response.status, response.headers.get("content-type", ""), response.read()


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """A fresh venv with the repository's wheel installed; returns its python."""
    root = tmp_path_factory.mktemp("wheel")
    # build from a copy: setuptools writes build/ and *.egg-info beside the sources it builds
    source = root / "source"
    shutil.copytree(
        REPO,
        source,
        ignore=shutil.ignore_patterns(".venv*", ".git", "build", "data", "test-artifacts", "__pycache__", "*.egg-info"),
    )
    shutil.copytree(REPO / "tests" / "data", source / "tests" / "data")
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(root / "dist"), str(source)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    (wheel,) = (root / "dist").glob("buoy_inspection-*.whl")
    venv.EnvBuilder(with_pip=False).create(root / "venv")
    python = root / "venv" / "bin" / "python"
    site = Path(
        subprocess.check_output(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], text=True
        ).strip()
    )
    (site / "borrowed_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    install = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "--quiet", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert install.returncode == 0, install.stdout + install.stderr
    return python


def test_the_wheel_carries_the_page_and_imports_from_site_packages(installed, tmp_path):
    where = subprocess.check_output(
        [str(installed), "-c", "import gcs, uavcore; print(gcs.__file__); print(uavcore.__file__)"],
        cwd=tmp_path,
        text=True,
    ).split()
    assert all("site-packages" in path and str(REPO) not in path for path in where), where
    page = Path(where[0]).parent / "web" / "index.html"
    assert page.is_file(), f"no map page in the installed package: {page}"


def test_buoy_gcs_serve_from_the_wheel_serves_the_map_page(installed, tmp_path):
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("BUOY_GCS_")}
    env["PYTHONPATH"] = ""
    server = subprocess.Popen(
        [str(installed.with_name("buoy-gcs")), "serve", "--port", str(port), "--db", str(tmp_path / "gcs.sqlite")],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        deadline = time.monotonic() + 180  # a fresh venv compiles every module on first import: slow when loaded
        while True:
            try:
                status, kind, body = _get(f"http://127.0.0.1:{port}/")
                break
            except OSError:
                assert server.poll() is None, server.communicate()[0]
                assert time.monotonic() < deadline, "the installed service did not answer within 180 s"
                time.sleep(0.2)
        assert status == 200 and "text/html" in kind
        assert b"<html" in body.lower()
        for asset in ("/web/app.js", "/web/style.css", "/web/vendor/uplot/uPlot.iife.min.js"):
            status, _, body = _get(f"http://127.0.0.1:{port}{asset}")
            assert status == 200 and body, asset
    finally:
        server.terminate()
        server.wait(timeout=10)
