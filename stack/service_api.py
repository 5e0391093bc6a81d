"""Small HTTP helpers for talking to the ground station's API (stdlib: the stack needs no HTTP client library)."""

from __future__ import annotations

import json
import urllib.error
import urllib.request

from stack.supervisor import SupervisorError


def http_ok(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=2) as response:
            return response.status == 200
    except (urllib.error.URLError, OSError):
        return False


def get_json(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=10) as response:
        return json.loads(response.read())


def post_json(url: str, body: dict, headers: dict) -> dict:
    request = urllib.request.Request(
        url, data=json.dumps(body).encode(), method="POST", headers={"Content-Type": "application/json", **headers}
    )
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            return json.loads(response.read())
    except urllib.error.HTTPError as error:
        raise SupervisorError(f"POST {url} answered {error.code}: {error.read().decode()[:500]}") from error
