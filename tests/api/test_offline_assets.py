"""Everything the page and the API docs load is served by the app itself: no CDN (field
laptops and the tests are offline)."""

from __future__ import annotations

import re
from collections.abc import Callable

from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings


def test_page_and_api_docs_load_only_local_assets(
    make_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(make_settings(mock_vehicles=0))) as client:
        for path in ("/", "/docs"):
            page = client.get(path)
            assert page.status_code == 200
            urls = re.findall(r'(?:src|href)="([^"]+)"', page.text)
            urls += re.findall(r"url: '([^']+)'", page.text)
            assert urls, path
            for url in urls:
                assert not url.startswith(("http://", "https://", "//")), (path, url)
                if url.startswith(("#", "data:")):
                    continue
                target = url if url.startswith("/") else "/" + url
                assert client.get(target).status_code == 200, (path, url)
        bundle = client.get("/vendor/swagger-ui/swagger-ui-bundle.js").text
        assert "SwaggerUIBundle" in bundle
        # Swagger UI 5 or later: 4.x cannot render this API's OpenAPI 3.1 document.
        version = re.search(r'PACKAGE_VERSION:"(\d+)\.', bundle)
        assert version is not None and int(version.group(1)) >= 5
