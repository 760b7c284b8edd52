"""Cross-site protection and access control, checked before any route runs.

A web page the operator visits must not be able to fly the fleet, and a request is never
trusted because of where it claims to come from. Every HTTP request passes, in order:

1. **Host allow-list** (400): the Host header must name this service (the names it is bound
   to, or the `allowed_hosts` setting). A foreign name means DNS rebinding.
2. **Origin check** (403) on state-changing methods (POST, PUT, PATCH, DELETE): a browser's
   `Origin` (or `Sec-Fetch-Site: cross-site`) must be the service's own origin or listed in
   `allowed_origins`. Clients that send no Origin (curl, scripts) pass this step.
3. **Token** (401 missing or wrong, 403 wrong role) on `/api/...` when tokens are configured
   (always when bound beyond loopback): `Authorization: Bearer <token>`, or the
   `fleetplan_token` cookie the browser page sets (SameSite=Strict, so other sites' requests
   never carry it). The operator token may do everything; the read-only token only GET.
4. **JSON bodies** (415): a state-changing request that declares a Content-Type, or sends a
   body, must declare ``application/json``: forms and ``text/plain`` (which browsers send
   cross-site without a CORS preflight) are refused.
"""

from __future__ import annotations

import contextlib
import hmac
import socket
from dataclasses import dataclass
from enum import StrEnum
from http.cookies import CookieError, SimpleCookie
from urllib.parse import unquote

from starlette.types import ASGIApp, Receive, Scope, Send

from gcs.api.errors import (
    ApiError,
    BadRequest,
    Forbidden,
    Unauthorized,
    UnsupportedMediaType,
    send_error,
)
from gcs.service.settings import Settings

__all__ = ["TOKEN_COOKIE", "AccessPolicy", "Role", "SecurityMiddleware", "bound_names"]

#: The cookie the browser page keeps the token in (EventSource cannot send headers).
TOKEN_COOKIE = "fleetplan_token"
#: Methods that change state; everything else only reads.
UNSAFE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})
_LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1")


class Role(StrEnum):
    """What a request's token allows: reading, or everything (plan, fly, abort, command)."""

    READ = "read"
    OPERATOR = "operator"


def bound_names(host: str) -> set[str]:
    """The Host names a service bound to `host` answers by default: the loopback names, the
    address itself, and for a wildcard bind (0.0.0.0, ::) this machine's name and
    addresses."""
    names = {*_LOOPBACK_NAMES, host.strip("[]").lower()}
    if host in ("0.0.0.0", "::", ""):
        hostname = socket.gethostname()
        names |= {hostname.lower(), socket.getfqdn().lower()}
        with contextlib.suppress(OSError):
            names |= set(socket.gethostbyname_ex(hostname)[2])
    return names


def _split_host(value: str) -> str:
    """The name of a Host header without its port (IPv6 literals keep no brackets)."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1:value.find("]")] if "]" in value else value
    return value.rsplit(":", 1)[0] if value.count(":") == 1 else value


@dataclass(frozen=True)
class AccessPolicy:
    """The checks' configuration, from the settings."""

    hosts: frozenset[str] | None
    """Allowed Host names; None: any."""
    origins: frozenset[str]
    """Origins allowed besides the service's own."""
    operator_token: str | None
    read_token: str | None

    @classmethod
    def from_settings(cls, settings: Settings) -> AccessPolicy:
        hosts: frozenset[str] | None
        if "*" in settings.allowed_hosts:
            hosts = None
        elif settings.allowed_hosts:
            hosts = frozenset(_split_host(h) for h in settings.allowed_hosts)
        else:
            hosts = frozenset(bound_names(settings.host))
        return cls(
            hosts=hosts,
            origins=frozenset(o.rstrip("/").lower() for o in settings.allowed_origins),
            operator_token=None if settings.api_token is None
            else settings.api_token.get_secret_value(),
            read_token=None if settings.read_token is None
            else settings.read_token.get_secret_value(),
        )

    @property
    def tokens_required(self) -> bool:
        return self.operator_token is not None

    def role_of(self, token: str | None) -> Role | None:
        """The role a presented token grants (constant-time comparisons), None if none."""
        if not self.tokens_required:
            return Role.OPERATOR
        if token is None:
            return None
        given = token.encode()
        if self.operator_token is not None and hmac.compare_digest(
                given, self.operator_token.encode()):
            return Role.OPERATOR
        if self.read_token is not None and hmac.compare_digest(given, self.read_token.encode()):
            return Role.READ
        return None


def _headers(scope: Scope) -> dict[str, str]:
    return {k.decode("latin-1").lower(): v.decode("latin-1")
            for k, v in scope.get("headers", [])}


def _presented_token(headers: dict[str, str]) -> str | None:
    authorization = headers.get("authorization", "")
    scheme, _, credentials = authorization.partition(" ")
    if scheme.lower() == "bearer" and credentials.strip():
        return credentials.strip()
    if "cookie" in headers:
        try:
            cookie = SimpleCookie(headers["cookie"])
        except CookieError:
            return None
        if TOKEN_COOKIE in cookie:
            return unquote(cookie[TOKEN_COOKIE].value)  # the page URI-encodes it
    return None


def _is_json(content_type: str) -> bool:
    media = content_type.split(";", 1)[0].strip().lower()
    return media == "application/json" or (media.startswith("application/")
                                           and media.endswith("+json"))


class SecurityMiddleware:
    """Pure ASGI middleware applying an `AccessPolicy` to every HTTP request."""

    def __init__(self, app: ASGIApp, policy: AccessPolicy) -> None:
        self.app = app
        self.policy = policy

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        error = self.check(scope["method"], scope.get("path", ""), scope.get("scheme", "http"),
                           _headers(scope))
        if error is not None:
            await send_error(send, error)
            return
        await self.app(scope, receive, send)

    def check(self, method: str, path: str, scheme: str,
              headers: dict[str, str]) -> ApiError | None:
        """The first check the request fails, or None."""
        host = headers.get("host", "")
        if self.policy.hosts is not None and _split_host(host) not in self.policy.hosts:
            return BadRequest("Host", f"this service does not answer to the name {host!r}; "
                              "add it to the allowed_hosts setting if it is this service")
        unsafe = method.upper() in UNSAFE_METHODS
        if unsafe:
            problem = self._cross_site(scheme, host, headers)
            if problem is not None:
                return problem
        if path.startswith("/api/") or path == "/api":
            role = self.policy.role_of(_presented_token(headers))
            if role is None:
                return self._unauthorized(headers)
            if unsafe and role is not Role.OPERATOR:
                return Forbidden("Authorization", "the read-only token may not change "
                                 "anything; use the operator token")
        if unsafe:
            content_type = headers.get("content-type")
            has_body = headers.get("content-length", "0") != "0" or (
                "transfer-encoding" in headers)
            if (content_type is not None or has_body) and not _is_json(content_type or ""):
                return UnsupportedMediaType(
                    "Content-Type", f"request bodies must be JSON (Content-Type: "
                    f"application/json), got {content_type or 'none'}")
        return None

    def _cross_site(self, scheme: str, host: str, headers: dict[str, str]) -> ApiError | None:
        origin = headers.get("origin")
        if origin is not None:
            origin = origin.rstrip("/").lower()
            own = f"{scheme}://{host}".lower()
            if origin != own and origin not in self.policy.origins:
                return Forbidden("Origin", f"cross-site request from {origin} refused; only "
                                 f"pages served by this service (or the allowed_origins "
                                 f"setting) may change anything")
        elif headers.get("sec-fetch-site") == "cross-site":
            return Forbidden("Origin", "cross-site request refused")
        return None

    @staticmethod
    def _unauthorized(headers: dict[str, str]) -> ApiError:
        presented = _presented_token(headers) is not None
        error = Unauthorized("Authorization", "wrong API token" if presented else
                             "an API token is required: Authorization: Bearer <token>")
        error.headers = {"WWW-Authenticate": "Bearer"}
        return error
