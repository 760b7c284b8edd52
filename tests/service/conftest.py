"""The service tests share the API tests' fixtures: isolated settings, a temporary database."""

from tests.api.conftest import _isolated_settings, make_settings, mock_settings

__all__ = ["_isolated_settings", "make_settings", "mock_settings"]
