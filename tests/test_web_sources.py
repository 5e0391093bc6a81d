"""Static checks of the map page's sources (gcs/web), no browser needed.

- The page names mission states only as MissionStatus.<name>, built at start from the service's OpenAPI enum;
  every name it uses must exist in that enum, so a state renamed on the server fails here.
- The page carries no list of states of its own (no quoted state strings in its scripts).
- Data never becomes markup: no innerHTML and the like in the scripts; no inline script or event handler in
  index.html (the page must run under a Content-Security-Policy of `script-src 'self'`).
"""

import re
from pathlib import Path

import pytest

from gcs.api.app import create_app
from gcs.settings import Settings

WEB = Settings().web_dir
SCRIPTS = sorted(WEB.glob("*.js"))  # the page's own modules; vendor/ holds third-party code
MODULES = {"app.js", "api.js", "state.js", "status.js", "map.js", "charts.js", "panel.js", "history.js", "verdicts.js",
           "controls.js", "confirm.js", "alerts.js", "times.js",
           "inspections.js", "findings.js", "gallery.js", "atons.js", "register.js", "alarms.js",
           "poll.js"}  # fmt: skip
MARKUP_FROM_STRINGS = re.compile(r"innerHTML|outerHTML|insertAdjacentHTML|document\.write|createContextualFragment")


def source(path: Path) -> str:
    return path.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def status_enum() -> list[str]:
    return create_app().openapi()["components"]["schemas"]["MissionStatus"]["enum"]


def test_the_page_has_its_scripts():
    assert {path.name for path in SCRIPTS} >= MODULES


def test_every_status_the_page_names_is_in_the_openapi_enum(status_enum):
    used = {name for path in SCRIPTS for name in re.findall(r"(?<![.\w])MissionStatus\.(\w+)", source(path))}
    assert used, "the page names no MissionStatus at all: the pattern or the sources changed"
    assert used <= set(status_enum), f"unknown to the service: {sorted(used - set(status_enum))}"


def test_the_page_keeps_no_list_of_statuses_of_its_own(status_enum):
    for path in SCRIPTS:
        quoted = re.findall(r"""["'`](\w+)["'`]""", source(path))
        assert not set(quoted) & set(status_enum), f"{path.name} spells a mission status as a string"


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_scripts_build_no_markup_from_strings(path):
    assert not MARKUP_FROM_STRINGS.search(source(path))


def test_index_has_no_inline_script_or_handler():
    index = source(WEB / "index.html")
    for tag in re.findall(r"<script\b[^>]*>(.*?)</script>", index, flags=re.S):
        assert not tag.strip(), "inline <script>: move it into a module"
    assert all(re.search(r"\bsrc=", tag) for tag in re.findall(r"<script\b[^>]*>", index))
    assert not re.search(r"\son[a-z]+\s*=", index), "inline event handler: use addEventListener in a module"
    assert "javascript:" not in index
