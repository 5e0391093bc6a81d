"""The files the MAVLink FTP tests serve (tests/test_sitl_ftp.py, tests/test_gcs_ftp_mavsdk_server.py)."""

from __future__ import annotations

import os
from pathlib import Path

from uavcore.mavftp import MAX_DATA


def served_files(root: Path) -> dict[str, bytes]:
    """A camera's kind of files: a ~200 kB JPEG, an empty file, one of exactly 150 * 239 bytes (a whole burst
    chunk, ending exactly at the end of a packet). Beside the root, a file a request must not reach."""
    root.mkdir()
    files = {
        "img_0001.jpg": b"\xff\xd8\xff\xe0" + os.urandom(200_000 - 6) + b"\xff\xd9",
        "empty.jpg": b"",
        "exact.bin": os.urandom(150 * MAX_DATA),
    }
    for name, content in files.items():
        (root / name).write_bytes(content)
    (root.parent / "outside.txt").write_text("not served")
    return files
