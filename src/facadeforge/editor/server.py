"""The local web server of ``facadeforge edit`` and ``facadeforge view`` (Starlette on uvicorn).

Safety, as SECURITY.md asks of every server we run:

- it binds to ``127.0.0.1`` only, and answers only clients on the loopback address;
- every request needs the session's random token (:func:`secrets.token_urlsafe`, 32 bytes):
  in the URL printed on the first line (``?token=…``), after which the page holds it in an
  ``HttpOnly``, ``SameSite=Strict`` cookie named after the port and sends it in the
  ``X-Facadeforge-Token`` header; a request without it, or with another ``Host`` than
  ``127.0.0.1:PORT`` / ``localhost:PORT`` (DNS rebinding), gets ``403``;
- the cookie alone opens only ``GET`` (pages, scripts, images: what the browser fetches by
  itself, and none of it changes anything).  A ``POST`` (an edit, a save) needs the token in
  the header or the query — which another site cannot send without a CORS pre-flight this
  server never grants — and, when the browser names an ``Origin``, this server's own: a page
  on another local port cannot edit through the user's cookie (cookies are per host, not per
  port);
- files are served only from the package's ``static/`` folder and, for ``view``, the kinds a
  model refers to (materials, textures, glTF buffers, tileset contents) from the folder of
  each file viewed (paths resolved and held inside it), with ``nosniff`` and a sandboxing
  ``Content-Security-Policy``;
- request bodies are at most :data:`MAX_BODY` bytes; edits are JSON checked by
  :mod:`.edits`, never code.

Errors come back as ``{"error": message}`` with 400 (a bad edit or input), 422 (rules that do
not derive) or 500.
"""

from __future__ import annotations

import hmac
import json
import secrets
import socket
import threading
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

from ..errors import DerivationError, FacadeForgeError, InputError, RuleError

__all__ = ["MAX_BODY", "STATIC", "Running", "editor_app", "serve", "start", "viewer_app"]

STATIC = Path(__file__).parent / "static"
#: Largest request body (an edit is a few hundred bytes).
MAX_BODY: int = 2**20
_COOKIE = "facadeforge_token_"     # + the port: two servers never overwrite each other's
_HEADER = "x-facadeforge-token"
_LOOPBACK = ("127.0.0.1", "::1")


class _Guard:
    """ASGI middleware: loopback clients with the token and our Host only."""

    def __init__(self, app, token: str, port_ref: list[int]):
        self.app, self.token, self.port_ref = app, token, port_ref

    async def __call__(self, scope, receive, send):
        if scope["type"] == "lifespan":
            return await self.app(scope, receive, send)
        if scope["type"] != "http":
            return await _refuse(send, "only HTTP")
        client = (scope.get("client") or ("", 0))[0]
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", [])}
        port = self.port_ref[0]
        if client not in _LOOPBACK:
            return await _refuse(send, "only clients on this machine")
        if headers.get("host") not in (f"127.0.0.1:{port}", f"localhost:{port}"):
            return await _refuse(send, "wrong Host")
        given = _query_token(scope.get("query_string", b"")) or headers.get(_HEADER)
        if not given and scope.get("method") in ("GET", "HEAD"):
            given = _cookie(headers.get("cookie", ""), port)
        if not given or not hmac.compare_digest(given.encode(), self.token.encode()):
            return await _refuse(send, "this server needs the token of the URL it printed")
        origin = headers.get("origin")
        if scope.get("method") not in ("GET", "HEAD") and origin is not None and origin not in (
                f"http://127.0.0.1:{port}", f"http://localhost:{port}"):
            return await _refuse(send, f"requests from {origin[:80]}")
        return await self.app(scope, receive, send)


async def _refuse(send, why: str) -> None:
    body = f"forbidden: {why}\n".encode()
    await send({"type": "http.response.start", "status": 403,
                "headers": [(b"content-type", b"text/plain; charset=utf-8"),
                            (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})


def _query_token(qs: bytes) -> str | None:
    from urllib.parse import parse_qs

    v = parse_qs(qs.decode("latin-1")).get("token")
    return v[0] if v else None


def _cookie(header: str, port: int) -> str | None:
    for part in header.split(";"):
        k, _, v = part.strip().partition("=")
        if k == f"{_COOKIE}{port}":
            return v
    return None


# -- responses ------------------------------------------------------------------------------------

def _error(e: Exception):
    from starlette.responses import JSONResponse

    if isinstance(e, InputError):
        status = 400
    elif isinstance(e, RuleError | DerivationError):
        status = 422
    else:
        status = 500
    msg = str(e) if isinstance(e, FacadeForgeError) else f"{type(e).__name__}: {e}"
    return JSONResponse({"error": msg}, status_code=status)


async def _json_body(request) -> object:
    body = b""
    async for chunk in request.stream():
        body += chunk
        if len(body) > MAX_BODY:
            raise InputError(f"request body larger than {MAX_BODY} bytes")
    try:
        return json.loads(body or b"null")
    except ValueError as e:
        raise InputError(f"request body is not JSON ({e})") from None


def _page(name: str, token: str, port: int):
    from starlette.responses import HTMLResponse

    html = (STATIC / name).read_text(encoding="utf-8")
    resp = HTMLResponse(html, headers={"Cache-Control": "no-store",
                                       "Content-Security-Policy":
                                       "default-src 'self'; img-src 'self' data: blob:; "
                                       "style-src 'self' 'unsafe-inline'; "
                                       "connect-src 'self' data: blob:"})
    resp.set_cookie(f"{_COOKIE}{port}", token, httponly=True, samesite="strict", path="/")
    return resp


def _base_routes(page: str, token: str) -> list:
    from starlette.responses import Response
    from starlette.routing import Mount, Route
    from starlette.staticfiles import StaticFiles

    async def index(request):
        return _page(page, token, request.url.port or 0)

    async def favicon(request):
        return Response(status_code=204)

    return [Route("/", index), Route("/favicon.ico", favicon),
            Mount("/static", StaticFiles(directory=STATIC), name="static")]


# -- the editor -----------------------------------------------------------------------------------

def editor_app(session, token: str):
    """The editor's ASGI app over an :class:`~facadeforge.editor.session.EditSession`."""
    from starlette.applications import Starlette
    from starlette.concurrency import run_in_threadpool
    from starlette.responses import JSONResponse, Response
    from starlette.routing import Route

    def guarded(fn: Callable):
        async def endpoint(request):
            try:
                return await fn(request)
            except Exception as e:   # noqa: BLE001 - every failure becomes a JSON error
                return _error(e)
        return endpoint

    def then_payload(fn, key: str, *args):
        """``fn(*args)`` and the state right after it, under the session's lock: the reply
        shows this request's result, never another one's half-done edit."""
        with session.lock:
            return {key: fn(*args), **session.payload()}

    async def state(request):
        return JSONResponse(await run_in_threadpool(session.payload))

    async def apply(request):
        edit = await _json_body(request)
        return JSONResponse(await run_in_threadpool(then_payload, session.apply, "result", edit))

    async def undo(request):
        return JSONResponse(await run_in_threadpool(then_payload, session.undo, "result"))

    async def redo(request):
        return JSONResponse(await run_in_threadpool(then_payload, session.redo, "result"))

    async def save(request):
        return JSONResponse(await run_in_threadpool(then_payload, session.save, "files"))

    async def model(request):
        return Response(session.glb(), media_type="model/gltf-binary",
                        headers={"Cache-Control": "no-store"})

    async def backdrop(request):
        return Response(await run_in_threadpool(session.backdrop_png), media_type="image/png",
                        headers={"Cache-Control": "no-store"})

    async def library(request):
        return JSONResponse(_library())

    async def thumb(request):
        return Response(await run_in_threadpool(_thumbnail, request.path_params["name"]),
                        media_type="image/png", headers={"Cache-Control": "max-age=3600"})

    routes = _base_routes("editor.html", token) + [
        Route("/api/state", guarded(state)),
        Route("/api/apply", guarded(apply), methods=["POST"]),
        Route("/api/undo", guarded(undo), methods=["POST"]),
        Route("/api/redo", guarded(redo), methods=["POST"]),
        Route("/api/save", guarded(save), methods=["POST"]),
        Route("/api/model.glb", guarded(model)),
        Route("/api/backdrop.png", guarded(backdrop)),
        Route("/api/library", guarded(library)),
        Route("/api/thumb/{name}.png", guarded(thumb)),
    ]
    return Starlette(routes=routes)


def _library() -> list[dict]:
    from ..elements.library import element_library

    return [{"name": s.name, "kind": s.kind, "mount": s.mount,
             "size_m": [round(v, 3) for v in s.size]} for s in element_library()]


@lru_cache(maxsize=512)
def _thumbnail(name: str) -> bytes:
    """A front render of a library element (§4 ``p(e_i)``), 96 px tall."""
    import numpy as np

    from ..elements.library import element_spec, render_front
    from .session import png_bytes

    spec = element_spec(name)          # InputError for an unknown name
    w, h = spec.size
    hp = 96
    wp = max(8, min(192, round(hp * w / max(h, 1e-6))))
    gray, _ = render_front(spec, wp, hp)
    g = (np.clip(gray, 0, 1) * 255).astype(np.uint8)
    return png_bytes(np.stack([g, g, g], -1))


# -- the viewer -----------------------------------------------------------------------------------

def viewer_app(scene, token: str):
    """The viewer's ASGI app over a :class:`~facadeforge.editor.scene.Scene`."""
    from starlette.applications import Starlette
    from starlette.responses import FileResponse, JSONResponse, Response
    from starlette.routing import Route

    async def info(request):
        return JSONResponse(scene.public())

    async def layer(request):
        try:
            la = scene.layers[int(request.path_params["index"])]
        except (ValueError, IndexError):
            return JSONResponse({"error": "no such layer"}, status_code=404)
        if la.payload is not None:
            return Response(la.payload, media_type="application/octet-stream")
        return FileResponse(la.path)

    async def file(request):
        """A file beside a layer (an OBJ's .mtl and textures, a tileset's content)."""
        try:
            la = scene.layers[int(request.path_params["index"])]
        except (ValueError, IndexError):
            return JSONResponse({"error": "no such layer"}, status_code=404)
        root = la.path.parent.resolve()
        target = (root / request.path_params["rest"]).resolve()
        if root not in target.parents or not target.is_file() or \
                target.suffix.lower() not in _BESIDE:
            return JSONResponse({"error": "not a file of this layer"}, status_code=404)
        return FileResponse(target, headers={"X-Content-Type-Options": "nosniff",
                                             "Content-Security-Policy": "sandbox"})

    routes = _base_routes("viewer.html", token) + [
        Route("/api/scene", info),
        Route("/api/layer/{index}", layer),
        Route("/api/file/{index}/{rest:path}", file),
    ]
    return Starlette(routes=routes)


#: What a model refers to beside itself: materials, textures, glTF buffers, tileset contents.
_BESIDE = frozenset({".mtl", ".png", ".jpg", ".jpeg", ".webp", ".bmp", ".tga", ".tif", ".tiff",
                     ".ktx2", ".bin", ".glb", ".gltf", ".json"})


# -- running --------------------------------------------------------------------------------------

class Running:
    """A server started by :func:`start`: ``url`` (with the token), ``stop()``."""

    def __init__(self, server, thread: threading.Thread, url: str, token: str, port: int):
        self.server, self.thread, self.url, self.token, self.port = (server, thread, url, token,
                                                                     port)

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=10)


def _bind(port: int) -> socket.socket:
    if not 0 <= int(port) <= 65535:
        raise InputError(f"--port {port}: give a port 1..65535, or 0 for any free one")
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(("127.0.0.1", int(port)))
    except OSError as e:
        sock.close()
        raise InputError(f"--port {port}: cannot listen on 127.0.0.1:{port} ({e.strerror}); "
                         "choose another port, or 0 for any free one") from None
    sock.listen(64)
    return sock


def _server(make_app: Callable[[str], object], port: int):
    import uvicorn

    token = secrets.token_urlsafe(32)
    port_ref = [0]                   # the guard learns the port once the socket is bound
    app = _Guard(make_app(token), token, port_ref)
    sock = _bind(port)
    port_ref[0] = sock.getsockname()[1]
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off")
    server = uvicorn.Server(config)
    url = f"http://127.0.0.1:{port_ref[0]}/?token={token}"
    return server, sock, url, token, port_ref[0]


def start(make_app: Callable[[str], object], port: int = 0) -> Running:
    """Serve ``make_app(token)`` in a background thread (tests, notebooks)."""
    server, sock, url, token, port = _server(make_app, port)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    for _ in range(500):
        if server.started:
            break
        threading.Event().wait(0.01)
    return Running(server, thread, url, token, port)


def serve(make_app: Callable[[str], object], port: int = 0, *, open_browser: bool = True,
          announce: Callable[[str], None] = print) -> None:
    """Serve until Ctrl-C; the URL with the token is the first line ``announce`` gets."""
    server, sock, url, _, _ = _server(make_app, port)
    announce(url)
    if open_browser:
        import webbrowser

        threading.Timer(0.5, webbrowser.open, args=(url,)).start()
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        pass
    finally:
        sock.close()
