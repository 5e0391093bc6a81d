"""The ground station's MAVLink FTP client against a server nobody here wrote: MAVSDK 4.1's FtpServer plugin
(tests/mavsdk_ftp_server.py), on the autopilot component and on a camera component of the same system.

The server pushes its MAVLink to the link's `udpin` port, as PX4 SITL does to QGroundControl. Every wait polls a
condition (the link connected, the download returned) against a generous deadline.

Where MAVSDK's server differs from ours and the client copes: it has one session (always 0); it fails a ReadFile
asking for more bytes than are left, so the client asks for exactly what is left; a path out of its root is "Fail"
(ours: FileNotFound); it paces its bursts (about 150 packets per burst).
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
from pathlib import Path

import pytest
from ftp_files import served_files
from sitl_process import REPO

from bench.processes import free_udp_port, stop_process
from gcs.vehicle.ftp import FileTooLargeError, FtpClient, FtpError
from gcs.vehicle.link import LinkManager
from uavcore.mavftp import NakError

pytestmark = [pytest.mark.integration, pytest.mark.timeout(300)]

SERVER_SCRIPT = REPO / "tests" / "mavsdk_ftp_server.py"
CONNECT_S = 60.0  # a backstop for a loaded machine


async def printed(log_path: Path, line: str, timeout_s: float) -> bool:
    """Whether the server printed `line` within `timeout_s` (polled: a loaded machine starts it late)."""
    deadline = asyncio.get_running_loop().time() + timeout_s
    while line not in log_path.read_text().splitlines():
        if asyncio.get_running_loop().time() > deadline:
            return False
        await asyncio.sleep(0.1)
    return True


@pytest.fixture
def served(tmp_path) -> tuple[Path, dict[str, bytes]]:
    root = tmp_path / "images"
    return root, served_files(root)


@pytest.mark.parametrize("component", [1, 100], ids=["autopilot", "camera"])
def test_the_ground_station_downloads_from_mavsdks_ftp_server(tmp_path, served, component):
    root, files = served
    port = free_udp_port()
    log_path = tmp_path / "mavsdk-ftp-server.log"

    async def scenario() -> None:
        link = LinkManager(f"udpin://127.0.0.1:{port}")
        await link.start()
        with log_path.open("w") as log:
            server = subprocess.Popen(
                [
                    sys.executable,
                    str(SERVER_SCRIPT),
                    "--connect",
                    f"udpout://127.0.0.1:{port}",
                    "--root",
                    str(root),
                    "--component",
                    str(component),
                ],
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        try:
            assert await link.wait_connected(CONNECT_S), f"no heartbeat from MAVSDK:\n{log_path.read_text()[-3000:]}"
            # MAVSDK heartbeats from the moment it connects, before the script has given FtpServer its directory;
            # an OpenFileRO in between is refused ("Fail"), so the test waits for the script to say it serves
            assert await printed(log_path, "ready", CONNECT_S), f"MAVSDK never served:\n{log_path.read_text()[-3000:]}"
            client = FtpClient(link)
            for name, content in files.items():
                assert await client.download(f"/{name}", component) == content, f"{name} by bursts"
                assert await client.download(f"/{name}", component, burst=False) == content, f"{name} by ReadFile"
            with pytest.raises(FtpError) as missing:
                await client.download("/missing.jpg", component)
            assert missing.value.error is NakError.FileNotFound, missing.value
            with pytest.raises(FtpError) as outside:
                await client.download("/../outside.txt", component)
            assert outside.value.error is NakError.Fail, outside.value  # MAVSDK: "Not inside root dir"
            with pytest.raises(FileTooLargeError):
                await client.download("/img_0001.jpg", component, max_bytes=1000)
            # MAVSDK has one session: the refused transfer above closed it, or this would be NoSessionsAvailable
            assert await client.download("/exact.bin", component) == files["exact.bin"]
        finally:
            stop_process(server, 10)
            await link.stop()
        assert server.returncode == 0, log_path.read_text()[-3000:]

    asyncio.run(scenario())
