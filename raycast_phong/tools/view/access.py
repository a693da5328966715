"""Who may use the view: the token, its cookie, the Host and Origin checks, and the headers every response carries.

Settings and access are kept apart. The token the command prints opens the page once: that response sets an
HttpOnly SameSite=Strict cookie, and the page removes the token from its address bar, so a permalink (the URL's
`#view=` fragment) carries settings only and sharing a view never shares access. A page loaded by the cookie may
not be framed by anyone (`frame-ancestors 'none'`, X-Frame-Options DENY): another page on 127.0.0.1 (another
port is the same site, so it would get the cookie) cannot frame the view and click it. Only a load that carries
the token itself may be framed, and only by loopback pages: a notebook's cell (notebook.live) holds the token.
"""

from __future__ import annotations

import re
import secrets
from pathlib import Path
from urllib.parse import quote

from starlette.requests import HTTPConnection, Request
from starlette.responses import HTMLResponse, PlainTextResponse, Response
from starlette.staticfiles import StaticFiles

STATIC = Path(__file__).parent / "static"
STATIC_LINK = re.compile(r'(src|href)="static/([A-Za-z0-9_.-]+)"')  # index.html's links to its own files
COOKIE = "raycast_phong_view_{port}"  # cookies ignore the port: one name per server, as Jupyter's
# Who may frame a page opened with the token (a notebook on loopback). CSP has no syntax for an IPv6 literal:
# Chromium rejects `http://[::1]:*` and logs an error on every load, so a notebook served on [::1] cannot frame
# the view (open Jupyter on localhost or 127.0.0.1).
LOOPBACK_FRAMERS = "http://localhost:* http://127.0.0.1:* https://localhost:* https://127.0.0.1:*"


def host_of(header: str) -> str:
    """The host name in a Host header or an origin's authority, without the port, lower case: `[::1]:8765` →
    `::1`, `localhost:8765` → `localhost`; "" when it is malformed (an IPv6 address without brackets)."""
    header = header.strip().lower()
    if header.startswith("["):
        return header[1:header.index("]")] if "]" in header else ""
    return "" if header.count(":") > 1 else header.split(":", 1)[0]


def cookie_name(connection: HTTPConnection) -> str:
    return COOKIE.format(port=connection.url.port or 80)


class Access:
    """The token's checks and the two things served over HTTP: the page and its own static files."""

    def __init__(self, token: str, on_page=None):
        self.token, self.on_page = token, on_page  # on_page(): told when the page is served (the warm-up starts)
        self.static_files = StaticFiles(directory=STATIC)

    def matches(self, given: str) -> bool:
        return secrets.compare_digest(given.encode(), self.token.encode())

    def in_url(self, connection: HTTPConnection) -> bool:
        """The request names the token itself (the printed URL, a notebook's frame), not only its cookie."""
        return self.matches(connection.query_params.get("token", ""))

    def authorised(self, connection: HTTPConnection) -> bool:
        given = connection.query_params.get("token") or connection.cookies.get(cookie_name(connection)) or ""
        return self.matches(given)

    @staticmethod
    def refused() -> Response:
        return PlainTextResponse("403: this page needs the token the `raycast-phong view` command printed; open "
                                 "the URL it printed (its token is kept in ~/.local/state/raycast-phong, so a "
                                 "restarted server prints the same one)\n", status_code=403)

    async def index(self, request: Request) -> Response:
        """The page. Opened with the token, its own files name the token too (framed by a notebook of another
        site, it gets no Strict cookie) and the response sets the cookie that later loads use."""
        if not self.authorised(request):
            return self.refused()
        page = (STATIC / "index.html").read_text(encoding="utf-8")
        if self.in_url(request):
            token = quote(self.token, safe="")
            page = STATIC_LINK.sub(lambda m: f'{m[1]}="static/{m[2]}?token={token}"', page)
        response = HTMLResponse(page, headers={"Cache-Control": "no-store"})
        response.set_cookie(cookie_name(request), self.token, httponly=True, samesite="strict")
        if self.on_page is not None:
            self.on_page()
        return response

    async def access(self, request: Request) -> Response:
        """204 if the token (the page's own, or its cookie) is good, else 403: a socket refused before its
        upgrade reaches the page as close code 1006 only, so the page asks here why."""
        return Response(status_code=204) if self.authorised(request) else self.refused()

    async def static(self, scope, receive, send) -> None:
        if not self.authorised(Request(scope)):
            return await self.refused()(scope, receive, send)
        await self.static_files(scope, receive, send)


class Guard:
    """ASGI middleware: refuse a Host the server was not asked for (DNS rebinding; 400, or the socket closed),
    and give every response the headers that keep the page to itself: a Content-Security-Policy (own scripts,
    styles and socket only; framed by nobody, or by loopback pages when the request carried the token), no
    referrer, no MIME sniffing."""

    def __init__(self, app, hosts: set[str], any_host: bool, access: Access):
        self.app, self.hosts, self.any_host, self.access = app, hosts, any_host, access

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        host = dict(scope["headers"]).get(b"host", b"").decode("latin-1")
        if not (host_of(host) and (self.any_host or host_of(host) in self.hosts)):
            if scope["type"] == "websocket":
                return await send({"type": "websocket.close", "code": 1008})
            return await PlainTextResponse("400: this server does not answer to that host name\n",
                                           status_code=400)(scope, receive, send)
        frameable = scope["type"] == "http" and self.access.in_url(HTTPConnection(scope))
        framers = LOOPBACK_FRAMERS if frameable else "'none'"
        policy = ("default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; "
                  f"connect-src 'self' blob: ws://{host}; base-uri 'none'; form-action 'none'; "
                  f"frame-ancestors {framers}")
        extra = [(b"content-security-policy", policy.encode("latin-1")), (b"referrer-policy", b"no-referrer"),
                 (b"x-content-type-options", b"nosniff")]
        if not frameable:
            extra.append((b"x-frame-options", b"DENY"))

        async def with_headers(message):
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), *extra]}
            await send(message)
        await self.app(scope, receive, with_headers)
