"""The API docs page and the page's token prompt, in a real browser (Debian's Chromium)."""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Dialog, expect

from tests.api.support import ServiceProcess
from tests.web.support import ServiceStarting

TOKEN = "browser-operator-token-0123"
#: What the header's service status shows once GET /api/status answered ("... · planning 0").
PLANNING = re.compile(r"planning \d+")


def test_docs_render_the_operations_list(browser: Browser, service: ServiceProcess) -> None:
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    page = context.new_page()
    page.goto(service.base_url + "/docs")
    operations = page.locator(".opblock")
    expect(operations.first).to_be_visible(timeout=20_000)
    assert operations.count() >= 15
    paths = page.locator(".opblock-summary-path").all_inner_texts()
    assert any(p.replace("\u200b", "") == "/api/missions" for p in paths), paths
    assert page.get_by_text("Unable to render this definition").count() == 0
    # The scenario body is documented by the planner-derived schema.
    assert page.locator(".models, .models-control").count() >= 1
    context.close()


@pytest.fixture(scope="module", autouse=True)
def token_service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServiceStarting]:
    """A service with an operator token (and no vehicles), started in the background when
    the module begins, so its start-up overlaps the docs test; `.ready()` waits for it."""
    starting = ServiceStarting(ServiceProcess(
        tmp_path_factory.mktemp("token"), "--mock", "0", "--workers", "1",
        env={"FLEETPLAN_API_TOKEN": TOKEN}, token=TOKEN))
    try:
        yield starting
    finally:
        starting.stop()


def test_the_page_asks_for_the_token_once_and_then_works(
    browser: Browser, token_service: ServiceStarting
) -> None:
    service = token_service.ready()
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    page = context.new_page()
    prompts: list[str] = []

    def answer(dialog: Dialog) -> None:
        prompts.append(dialog.message)
        dialog.accept(TOKEN)

    page.on("dialog", answer)
    page.goto(service.base_url + "/")
    expect(page.locator("#service-status")).to_contain_text(PLANNING, timeout=20_000)
    assert len(prompts) == 1 and "API token" in prompts[0]
    cookies = {c["name"]: c for c in context.cookies()}
    assert cookies["fleetplan_token"]["sameSite"] == "Strict"
    # Later requests (a reload too) go through without asking again.
    page.reload()
    expect(page.locator("#service-status")).to_contain_text(PLANNING, timeout=20_000)
    assert len(prompts) == 1
    context.close()
