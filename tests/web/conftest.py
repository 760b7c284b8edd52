"""Fixtures for the browser tests: Debian's Chromium driven by Playwright, and the service.

No browser download happens here: Playwright launches /usr/bin/chromium (Debian package
`chromium`). Without it the tests skip with how to install it, except where
FLEETPLAN_REQUIRE_BROWSER=1 (CI), where a missing browser is a failure.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import (
    Browser,
    BrowserContext,
    Page,
    Route,
    ViewportSize,
    expect,
    sync_playwright,
)

from tests.api.support import ServiceProcess, free_udp_base
from tests.support.waiting import wait_for
from tests.web.support import ServiceStarting

CHROMIUM = os.environ.get("FLEETPLAN_CHROMIUM", "/usr/bin/chromium")
#: How long a page expectation waits by default (ms): a loose bound, not a timing check. On a
#: machine busy beside the suite (two CPU hogs) the page took over Playwright's 5 s default to
#: enable Plan; a passing expectation returns as soon as it holds, whatever the bound.
EXPECT_TIMEOUT_MS = 30_000
expect.set_options(timeout=EXPECT_TIMEOUT_MS)


def _chromium() -> str:
    path = CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium")
    if path:
        return path
    message = ("Chromium not found: install Debian's package (sudo apt-get install chromium) "
               "or set FLEETPLAN_CHROMIUM; `make test` installs it when run as root")
    if os.environ.get("FLEETPLAN_REQUIRE_BROWSER") == "1":
        pytest.fail(message)
    pytest.skip(message)


@pytest.fixture(scope="session")
def service_starting(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServiceStarting]:
    """`fleetplan serve` with 4 mock vehicles on free ports, booting in the background while
    Chromium launches."""
    workdir = tmp_path_factory.mktemp("web")
    env = {"FLEETPLAN_MOCK_BASE_PORT": str(free_udp_base(4)), "FLEETPLAN_MOCK_SETTLE_S": "0.2"}
    starting = ServiceStarting(ServiceProcess(workdir, "--mock", "4", "--workers", "1",
                                              env=env, quick_mocks=True))
    try:
        yield starting
    finally:
        starting.stop()


@pytest.fixture(scope="module")
def browser(service_starting: ServiceStarting) -> Iterator[Browser]:
    """One Chromium per test file: every test opens its own context (cookies, routes).
    Playwright's sync API keeps an event loop running in the process while it is open, so
    it is closed with the file: later tests in the same process may run their own loop.
    Asking for it starts the service too, so the two boot together."""
    executable = _chromium()
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=executable, headless=True)
        try:
            yield launched
        finally:
            launched.close()


@pytest.fixture(scope="session")
def service(service_starting: ServiceStarting) -> ServiceProcess:
    """The service shared by every browser test of the process: each test opens its own
    page, and each flight a test starts ends before the test does."""
    return service_starting.ready()


@pytest.fixture(autouse=True)
def no_flight_left(request: pytest.FixtureRequest) -> Iterator[None]:
    """A test that fails mid-flight leaves no flight behind for the next test (which would
    see it as a flight started elsewhere, or be refused a flight of its own): aborted, and
    waited for (a loose bound) until it has landed."""
    yield
    if "service" not in request.fixturenames:
        return
    base = request.getfixturevalue("service").base_url
    flying = httpx.get(f"{base}/api/vehicles", timeout=30).json()["fleet"]["flying"]
    if flying is None:
        return
    httpx.post(f"{base}/api/flights/{flying}/abort", json={"action": "land"}, timeout=30)
    wait_for(lambda: httpx.get(f"{base}/api/flights/{flying}", timeout=30).json()["finished_at"],
             f"the aborted flight {flying} to land", timeout=120.0, poll=0.1)


#: How the page's Fly flies in these tests (the page itself sends no options): a tracking
#: bound the mocks keep even when a starved machine stalls the service's loop (the mocks run
#: in it) for 2 s; a 2 m/s climb and a short prestream; the hold at the goals stays the
#: default, which lets a vehicle that fell behind reach its goal before it is judged. The
#: flight's own checks are in tests/flight.
FLY_OPTIONS = {"tracking_error_max": 3.0, "climb_speed": 2.0, "prestream": 0.3}
FLY_REQUEST = re.compile(r".*/api/missions/[^/]+/flights$")


def _quick_flights(route: Route) -> None:
    request = route.request
    if request.method != "POST":
        route.fallback()
        return
    assert request.post_data is None, request.post_data  # the page sends no options
    route.fallback(post_data=json.dumps(FLY_OPTIONS),
                   headers={**request.headers, "content-type": "application/json"})


#: The operator's screens the page is made for: a laptop and a phone.
DESKTOP: ViewportSize = {"width": 1440, "height": 900}
PHONE: ViewportSize = {"width": 390, "height": 844}


@pytest.fixture
def open_page(browser: Browser, service: ServiceProcess) -> Iterator[Callable[..., Page]]:
    """open_page(viewport, before=None, has_touch=False): a fresh page on the service;
    `before(page)` runs before it loads (to install routes; they take precedence over the
    FLY_OPTIONS route); `has_touch` gives it touch events, as a phone has. Every page must end
    without JavaScript errors."""
    contexts: list[tuple[BrowserContext, list[str]]] = []

    def opener(viewport: ViewportSize = DESKTOP,
               before: Callable[[Page], None] | None = None, has_touch: bool = False) -> Page:
        context = browser.new_context(viewport=viewport, has_touch=has_touch)
        opened = context.new_page()
        errors: list[str] = []
        opened.on("pageerror", lambda exc: errors.append(str(exc)))
        contexts.append((context, errors))
        opened.route(FLY_REQUEST, _quick_flights)
        if before is not None:
            before(opened)
        opened.goto(service.base_url + "/")
        return opened

    yield opener
    for context, errors in contexts:
        context.close()
        assert not errors, f"JavaScript errors on the page: {errors}"


@pytest.fixture
def page(open_page: Callable[..., Page]) -> Page:
    """The page at 1440x900."""
    return open_page(DESKTOP)
