"""Which requests the editor's server trusts: only its own page (docs/editor.md, "Security").

A page from any other origin that the same browser has open could otherwise reach the server on
127.0.0.1 (a "simple" cross-origin POST needs no permission), and a DNS-rebinding site could
talk to it under a name of its own. So, as Jupyter does, every launch makes a secret token, and
a request is answered only if:

- its ``Host`` header names this server (``127.0.0.1:PORT``, ``localhost:PORT``,
  ``[::1]:PORT``, or the ``--host`` it was started with), against DNS rebinding;
- an ``Origin`` header, when the browser sends one, is ``http://`` + one of those hosts;
- an API call (``/api/...``) carries the token in the ``X-Sgjax-Token`` header (a custom header:
  a cross-origin page cannot send it without a CORS preflight, which this server never grants);
- a ``POST`` says ``Content-Type: application/json``.

The page reads the token from its own URL (``/?token=...``, the address ``sgjax edit`` prints
and opens), so nothing else on the machine learns it.
"""

from __future__ import annotations

import hmac
import secrets
import socket
from collections.abc import Mapping

from sgjax.editor.session import EditorError

TOKEN_HEADER = "X-Sgjax-Token"
TOKEN_BYTES = 24  # of randomness: 32 URL-safe characters
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")  # --host values that only this machine reaches
WILDCARD_HOSTS = ("0.0.0.0", "::", "")


def new_token() -> str:
    """A fresh secret for one launch of the server."""
    return secrets.token_urlsafe(TOKEN_BYTES)


def host_names(bound: str) -> tuple[str, ...]:
    """The names a browser may use for a server bound to ``bound`` (without the port): the
    loopback names, ``bound`` itself, and for a wildcard bind this machine's host names."""
    names = [*LOOPBACK_HOSTS]
    if bound in WILDCARD_HOSTS:
        names += [socket.gethostname(), socket.getfqdn()]
    else:
        names.append(bound)
    return tuple(dict.fromkeys(url_host(name).lower() for name in names if name))


def url_host(host: str) -> str:
    """``host`` as it stands in a URL or a ``Host`` header (an IPv6 address in brackets)."""
    return f"[{host}]" if ":" in host else host


class RequestGuard:
    """Checks one server's requests (``bound``: the address it listens on, ``port``, ``token``)."""

    def __init__(self, bound: str, port: int, token: str):
        self.token = token
        self.hosts = frozenset(f"{name}:{port}" for name in host_names(bound))
        self.origins = frozenset(f"http://{host}" for host in self.hosts)

    def check(self, method: str, path: str, headers: Mapping[str, str]) -> None:
        """Raise :class:`EditorError` (403 or 415) unless the request may be answered."""
        host = (headers.get("Host") or "").strip().lower()
        if host not in self.hosts:
            raise EditorError(403, f"refused: Host {host or '(none)'!r} is not this editor's "
                                   f"address ({', '.join(sorted(self.hosts))})")
        origin = headers.get("Origin")
        if origin is not None and origin.strip().lower() not in self.origins:
            raise EditorError(403, f"refused: a request from the page at {origin!r}; only the "
                                   "editor's own page may call it")
        if not path.startswith("/api/"):
            return
        given = headers.get(TOKEN_HEADER) or ""
        if not hmac.compare_digest(given.encode(), self.token.encode()):
            raise EditorError(403, f"refused: no valid {TOKEN_HEADER} header; open the address "
                                   "that `sgjax edit` printed (it carries the token)")
        if method == "POST":
            kind = (headers.get("Content-Type") or "").split(";", 1)[0].strip().lower()
            if kind != "application/json":
                raise EditorError(415, f"refused: Content-Type {kind or '(none)'!r}; the API "
                                       "takes application/json")
