"""The API tests' fixtures (isolated settings, `make_settings` on a temporary database) for
the service tests that run the real app."""

from tests.api.conftest import _isolated_settings, make_settings, mock_settings

__all__ = ["_isolated_settings", "make_settings", "mock_settings"]
