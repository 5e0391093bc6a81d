"""/docs (Swagger UI) and /redoc work with no network: their scripts, styles and icon come from the service
(gcs.api.app serves the fastapi-offline wheel's copies under /static/docs), never from a CDN. First the pages' HTML
and assets through the app in a TestClient; then both pages in headless Chromium against the real service, every
request to another host refused, until Swagger UI lists POST /missions and ReDoc has drawn the API."""

from __future__ import annotations

import re
from urllib.parse import urlsplit

import pytest
from fastapi.testclient import TestClient
from playwright.sync_api import ConsoleMessage, Route, expect, sync_playwright
from service_process import serving
from test_web_browser import ARTIFACTS, open_page

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.settings import Settings

DOC_PAGES = ("/docs", "/redoc")
ASSET_TYPES = {".js": ("text/javascript", "application/javascript"), ".css": ("text/css",), ".png": ("image/png",)}
# ReDoc's "API docs by Redocly" footer names its logo on the vendor's CDN: the docs' img-src ('self' data:)
# stops it before any request, and the page is whole without it
REDOCLY_LOGO = "https://cdn.redoc.ly/"
WAIT_MS = 30_000  # a backstop for a loaded machine: each wait ends as soon as its condition holds


@pytest.fixture
def client(tmp_path) -> TestClient:
    """The app without its lifespan (no planner warm-up, no vehicle link): the docs pages need neither."""
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    return TestClient(create_app(settings))


def named_urls(html: str) -> list[str]:
    """Every URL a page's markup names: src= and href= attributes."""
    return re.findall(r"""\b(?:src|href)\s*=\s*["']([^"']+)["']""", html)


def test_the_docs_pages_name_only_assets_the_service_serves(client):
    for path in DOC_PAGES:
        page = client.get(path)
        assert page.status_code == 200 and page.headers["content-type"].startswith("text/html"), path
        assert "cdn" not in page.text.lower() and "http" not in page.text.lower(), page.text
        urls = named_urls(page.text)
        assert any(url.endswith(".js") for url in urls), urls  # Swagger UI's or ReDoc's bundle
        for url in urls:
            assert url.startswith("/static/docs/") and not url.startswith("//"), url
            asset = client.get(url)
            suffix = url[url.rindex(".") :]
            assert asset.status_code == 200, url
            assert asset.headers["content-type"].split(";")[0] in ASSET_TYPES[suffix], (url, asset.headers)
    assert "swagger-ui.css" in client.get("/docs").text  # the stylesheet too, not only the script


def test_the_docs_pages_policy_allows_no_other_origin_and_they_stay_out_of_openapi(client):
    for path in (*DOC_PAGES, "/docs/oauth2-redirect"):
        answer = client.get(path)
        assert answer.status_code == 200, path
        sources = answer.headers["content-security-policy"].replace(";", " ").split()
        assert not [source for source in sources if ":" in source and source not in ("data:", "blob:")], sources
    paths = client.get("/openapi.json").json()["paths"]
    assert not [path for path in paths if path.startswith(("/docs", "/redoc", "/static"))]


@pytest.mark.browser
@pytest.mark.integration
@pytest.mark.slow
def test_swagger_ui_and_redoc_render_with_every_other_host_unreachable(tmp_path):
    errors: list[str] = []
    refused: list[str] = []  # requests to any host but the service's
    violations: list[str] = []  # Chromium logs each Content-Security-Policy violation
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url, sync_playwright() as p:
        origin = urlsplit(url).netloc

        def only_the_service(route: Route) -> None:
            if urlsplit(route.request.url).netloc == origin:
                route.continue_()
            else:
                refused.append(route.request.url)
                route.abort("internetdisconnected")

        def note_violation(message: ConsoleMessage) -> None:
            if "Content Security Policy" in message.text:
                violations.append(message.text)

        browser, page = open_page(p, errors)
        page.route("**/*", only_the_service)
        page.on("console", note_violation)
        page.goto(f"{url}/docs")
        # Swagger UI has fetched /openapi.json and lists the operations, POST /missions among them
        create_mission = page.locator('.opblock-post .opblock-summary-path[data-path="/missions"]')
        expect(create_mission).to_have_count(1, timeout=WAIT_MS)
        expect(page.locator(".opblock").first).to_be_visible()
        page.screenshot(path=str(ARTIFACTS / "docs_swagger_offline.png"))
        page.goto(f"{url}/redoc")
        # the API's title, then POST /missions by its summary
        expect(page.locator("h1").first).to_contain_text("buoy-gcs", timeout=WAIT_MS)
        expect(page.get_by_role("heading", name="Create Mission")).to_have_count(1, timeout=WAIT_MS)
        page.screenshot(path=str(ARTIFACTS / "docs_redoc_offline.png"))
        browser.close()
    assert errors == []
    assert refused == []
    assert [text for text in violations if REDOCLY_LOGO not in text] == []
