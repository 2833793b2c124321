"""facadeforge.editor.server, run for real on 127.0.0.1 (no browser): the token, the Host
check, the API, errors as JSON."""

from __future__ import annotations

import json
import socket
import urllib.error
import urllib.request

import pytest

from facadeforge.editor.server import editor_app, start, viewer_app
from facadeforge.editor.session import EditSession


@pytest.fixture
def running(outdir):
    session = EditSession(outdir)
    srv = start(lambda token: editor_app(session, token))
    yield srv, session
    srv.stop()


def _get(url, token=None, data=None, headers=None):
    h = dict(headers or {})
    if token:
        h["X-Facadeforge-Token"] = token
    req = urllib.request.Request(url, data=None if data is None else json.dumps(data).encode(),
                                 headers=h, method="POST" if data is not None else "GET")
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read(), dict(r.headers)
    except urllib.error.HTTPError as e:
        return e.code, e.read(), dict(e.headers)


def test_binds_to_loopback_and_prints_the_token_url(running):
    srv, _ = running
    assert srv.url.startswith(f"http://127.0.0.1:{srv.port}/?token=")
    assert len(srv.token) >= 40
    sockname = srv.server.servers[0].sockets[0].getsockname()
    assert sockname[0] == "127.0.0.1"


@pytest.mark.parametrize("path", ["/", "/api/state", "/api/model.glb", "/static/editor.js",
                                  "/api/thumb/window_wood_2x3.png"])
def test_requests_without_the_token_are_refused(running, path):
    srv, _ = running
    base = f"http://127.0.0.1:{srv.port}"
    status, body, _ = _get(base + path)
    assert status == 403 and b"token" in body
    status, _, _ = _get(base + path, token="x" * len(srv.token))
    assert status == 403


def test_another_host_header_is_refused(running):
    srv, _ = running
    status, body, _ = _get(srv.url, headers={"Host": f"evil.example:{srv.port}"})
    assert status == 403 and b"Host" in body


def test_the_page_sets_a_strict_cookie_and_the_api_answers(running):
    srv, _ = running
    status, body, headers = _get(srv.url)
    assert status == 200 and b"window.facadeforge" not in body and b"editor.js" in body
    cookie = headers.get("set-cookie", "")
    assert "HttpOnly" in cookie and "SameSite=strict" in cookie.replace("Strict", "strict")
    base = f"http://127.0.0.1:{srv.port}"
    status, body, _ = _get(base + "/static/editor.js",
                           headers={"Cookie": cookie.split(";")[0]})
    assert status == 200 and b"window.facadeforge" in body
    status, body, _ = _get(base + "/api/state", token=srv.token)
    data = json.loads(body)
    assert data["tree"]["symbol"] == "Facade" and data["state"]["version"] == 0


def test_apply_undo_save_and_errors_over_http(running, outdir):
    srv, session = running
    base = f"http://127.0.0.1:{srv.port}"
    rules0 = (outdir / "rules.cga").read_text()
    status, body, _ = _get(base + "/api/apply", srv.token,
                           {"op": "move_split", "path": [], "index": 1, "delta": 0.3})
    assert status == 200 and json.loads(body)["state"]["version"] == 1
    status, body, _ = _get(base + "/api/model.glb", srv.token)
    assert status == 200 and body[:4] == b"glTF"
    status, body, _ = _get(base + "/api/apply", srv.token, {"op": "set_depth", "path": [],
                                                           "depth": "x"})
    assert status == 400 and "not an element" in json.loads(body)["error"]
    status, body, _ = _get(base + "/api/apply", srv.token, {"op": "__import__('os')"})
    assert status == 400 and "unknown" in json.loads(body)["error"]
    status, body, _ = _get(base + "/api/save", srv.token, {})
    assert status == 200 and "rules.cga" in json.loads(body)["files"]
    assert (outdir / "rules.cga").read_text() != rules0
    status, body, _ = _get(base + "/api/thumb/nope.png", srv.token)
    assert status == 400


def test_the_cookie_alone_cannot_edit_and_other_origins_are_refused(running):
    srv, session = running
    base = f"http://127.0.0.1:{srv.port}"
    _, _, headers = _get(srv.url)
    cookie = headers.get("set-cookie", "").split(";")[0]
    assert cookie.startswith(f"facadeforge_token_{srv.port}=")     # one cookie per server
    edit = {"op": "move_split", "path": [], "index": 1, "delta": 0.1}
    status, _, _ = _get(base + "/api/apply", data=edit, headers={"Cookie": cookie})
    assert status == 403                 # what a page on another local port could send
    status, body, _ = _get(base + "/api/apply", srv.token, edit,
                           headers={"Origin": "http://127.0.0.1:8888"})
    assert status == 403 and b"8888" in body
    assert session.version == 0
    status, _, _ = _get(base + "/api/apply", srv.token, edit, headers={"Origin": base})
    assert status == 200 and session.version == 1
    status, _, _ = _get(base + "/api/state", headers={"Cookie": cookie})   # reading: fine
    assert status == 200


def test_a_huge_body_is_refused(running):
    srv, _ = running
    status, body, _ = _get(f"http://127.0.0.1:{srv.port}/api/apply", srv.token,
                           {"op": "move_split", "pad": "x" * (2 << 20)})
    assert status == 400 and b"larger than" in body


def test_a_port_in_use_is_a_clear_error(running):
    srv, session = running
    from facadeforge.errors import InputError

    with pytest.raises(InputError, match=f"--port {srv.port}: cannot listen"):
        start(lambda token: editor_app(session, token), srv.port)


def test_the_viewer_serves_only_files_beside_its_layers(reconstructed, tmp_path):
    from facadeforge.editor.scene import load_scene

    secret = tmp_path / "secret.txt"
    secret.write_text("no")
    (reconstructed / "page.html").write_text("<script>alert(1)</script>")
    scene = load_scene([reconstructed / "model.obj"])
    srv = start(lambda token: viewer_app(scene, token))
    try:
        base = f"http://127.0.0.1:{srv.port}"
        status, body, _ = _get(base + "/api/scene", srv.token)
        assert json.loads(body)["layers"][0]["kind"] == "obj"
        status, body, _ = _get(base + "/api/file/0/model.mtl", srv.token)
        assert status == 200 and b"newmtl" in body
        for bad in ("../secret.txt", "..%2Fsecret.txt", "/etc/passwd", "%2Fetc%2Fpasswd",
                    "page.html", "shape_tree.json.bak"):
            status, _, _ = _get(base + "/api/file/0/" + bad, srv.token)
            assert status == 404, bad
        status, _, headers = _get(base + "/api/file/0/model.mtl", srv.token)
        assert headers.get("x-content-type-options") == "nosniff"
        assert headers.get("content-security-policy") == "sandbox"
    finally:
        srv.stop()


def test_no_other_interface_answers(running):
    srv, _ = running
    addrs = {ai[4][0] for ai in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)}
    addrs.discard("127.0.0.1")
    addrs = {a for a in addrs if not a.startswith("127.")}
    for a in addrs:
        with pytest.raises(OSError):
            socket.create_connection((a, srv.port), timeout=2).close()
