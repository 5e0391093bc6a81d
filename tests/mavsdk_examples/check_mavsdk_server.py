"""Fail unless the mavsdk_server binary bundled with MAVSDK-Python runs on this machine.

`make test` runs this with .venv-mavsdk3's python right after installing the wheel: the binary is a prebuilt
executable, and a wheel for another platform (or one without the binary) must stop the build, not the tests.
"""

import subprocess
import sys
from importlib.metadata import version
from importlib.resources import files

import mavsdk

server = files(mavsdk) / "bin" / "mavsdk_server"
try:
    result = subprocess.run([str(server), "--help"], capture_output=True, text=True, timeout=30)
except OSError as exc:
    sys.exit(f"{server} does not run here: {exc}")
if result.returncode != 0 or "Usage" not in result.stdout:
    sys.exit(f"{server} --help exited {result.returncode}:\n{result.stdout}{result.stderr}")
print(f"mavsdk {version('mavsdk')}: {server} runs")
