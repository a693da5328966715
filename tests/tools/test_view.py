"""`raycast-phong view`'s server (raycast_phong/tools/view/server.py) through Starlette's TestClient, and the command
through a real uvicorn process: the token and Origin checks, the static folder, the CLI's one-line messages,
frames equal to render(), latest-wins, saves, the dragged light."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("starlette", reason="the view's server needs the [view] extra")
from conftest import write_tiny_scene
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app as cli_app
from raycast_phong.io.encoding import to_8bit
from raycast_phong.tools import accuracy
from raycast_phong.tools.view.server import (
    create_app,
    draft_of,
    frame_of,
    open_scene,
    scene_with,
    session_render,
    unpack,
)

TOKEN = "test-token"
ORIGIN = "http://testserver"  # TestClient's own origin


@pytest.fixture
def scene_path(tmp_path) -> Path:
    return write_tiny_scene(tmp_path, 64, 48)


def client_for(path: Path, **options) -> TestClient:
    return TestClient(create_app(open_scene(path), TOKEN, [ORIGIN], **options))


def connect(client: TestClient, token: str = TOKEN, origin: str | None = ORIGIN):
    headers = {"origin": origin} if origin is not None else {}
    return client.websocket_connect(f"/socket?token={token}", headers=headers)


def decode_png(data: bytes, folder: Path) -> np.ndarray:
    path = folder / "frame.png"
    path.write_bytes(data)
    return np.round(rp.read_image(path)[0] * 255).astype(np.uint8)  # read_image gives 8-bit values / 255


def rendered_png(scene: rp.Scene) -> np.ndarray:
    """What `raycast-phong render -o x.png` stores for the scene: the 8-bit values, encoded as its render.colour
    says."""
    result = rp.render(scene)
    return to_8bit(result.image, result.colour)


def receive_frame(ws) -> tuple[dict, dict]:
    """The next frame, past the progress messages of a full one."""
    message = ws.receive()
    while message.get("text") is not None:
        assert json.loads(message["text"])["type"] == "progress", message["text"]
        message = ws.receive()
    header, parts = unpack(message["bytes"])
    assert header["type"] == "frame", header
    return header, parts


# ---------------------------------------------------------------- access


def test_page_and_its_files_need_the_token(scene_path):
    client = client_for(scene_path)
    for url in ("/", "/?token=wrong", "/static/view.js", "/static/view.js?token=wrong"):
        response = client.get(url)
        assert response.status_code == 403, url
        assert "token" in response.text
    page = client.get(f"/?token={TOKEN}")
    assert page.status_code == 200 and "<html" in page.text
    # Its own script comes with the token in its URL too: framed by a notebook of another site, it has no cookie.
    assert f'src="static/view.js?token={TOKEN}"' in page.text
    assert client.get("/static/view.js").status_code == 200  # the page's files come with its cookie
    # The cookie: HttpOnly (no script reads it) and SameSite=Strict (no other site's page sends it), as
    # docs/view.md's Security says.
    attributes = [part.strip().lower() for part in page.headers["set-cookie"].split(";")]
    assert "httponly" in attributes and "samesite=strict" in attributes, attributes


def test_socket_without_the_token_or_from_another_origin_is_closed(scene_path):
    client = client_for(scene_path)
    for token, origin in (("", ORIGIN), ("wrong", ORIGIN), (TOKEN, "http://evil.example"), (TOKEN, None),
                          (TOKEN, "null")):
        with pytest.raises(WebSocketDisconnect) as refused:
            with connect(client, token, origin) as ws:
                ws.receive_text()
        assert refused.value.code == 1008, (token, origin)
    with connect(client) as ws:
        assert json.loads(ws.receive_text())["type"] == "hello"


def test_no_file_outside_the_static_folder_is_served(scene_path):
    client = client_for(scene_path)
    client.get(f"/?token={TOKEN}")
    for url in ("/static/../server.py", "/static/%2e%2e/server.py", "/static/..%2fserver.py",
                "/static/%2e%2e%2f%2e%2e%2fscene.py", "/static//etc/passwd", "/server.py"):
        response = client.get(url)
        assert response.status_code in (403, 404), url
        assert "def create_app" not in response.text and "root:" not in response.text, url


def test_a_host_name_other_than_the_servers_is_refused(scene_path):
    """DNS rebinding: a page of another site resolving to 127.0.0.1 still names its own host."""
    response = client_for(scene_path).get(f"/?token={TOKEN}", headers={"host": "evil.example"})
    assert response.status_code == 400


def test_host_names_in_brackets_and_wildcard_addresses(scene_path):
    """--host ::1 answers its own URL (a Host of [::1]:port); --host 0.0.0.0 answers any host name, and then
    the socket's Origin must be the page of the host it asked."""
    from raycast_phong.tools.view import origins_for, page_url
    assert page_url("::1", 8765, "t") == "http://[::1]:8765/?token=t" and origins_for("::1", 8765)[0] == "http://[::1]:8765"
    assert page_url("0.0.0.0", 8765, "t") == "http://127.0.0.1:8765/?token=t"  # the wildcard, reached here
    ipv6 = create_app(open_scene(scene_path), TOKEN, ["http://[::1]:8765"])
    assert TestClient(ipv6).get(f"/?token={TOKEN}", headers={"host": "[::1]:8765"}).status_code == 200
    for bad in ("::1", "evil.example", "[::1"):
        assert TestClient(ipv6).get(f"/?token={TOKEN}", headers={"host": bad}).status_code == 400, bad
    wildcard = TestClient(create_app(open_scene(scene_path), TOKEN, ["http://127.0.0.1:8765"], any_host=True))
    assert wildcard.get(f"/?token={TOKEN}", headers={"host": "lab-pc.local:8765"}).status_code == 200
    with wildcard.websocket_connect(f"/socket?token={TOKEN}", headers={"host": "lab-pc.local:8765",
                                                                       "origin": "http://lab-pc.local:8765"}) as ws:
        assert json.loads(ws.receive_text())["type"] == "hello"
    with pytest.raises(WebSocketDisconnect):
        with wildcard.websocket_connect(f"/socket?token={TOKEN}", headers={"host": "lab-pc.local:8765",
                                                                           "origin": "http://evil.example"}) as ws:
            ws.receive_text()


def test_every_response_keeps_the_page_to_itself(scene_path):
    client = client_for(scene_path)
    for url, status in ((f"/?token={TOKEN}", 200), ("/", 200), ("/static/view.js", 200), ("/?token=wrong", 403)):
        response = client.get(url)
        assert response.status_code == status
        policy = response.headers["content-security-policy"]
        assert "default-src 'none'" in policy and "script-src 'self'" in policy
        assert "connect-src 'self' blob: ws://testserver" in policy  # blob: the page's own frames and downloads
        assert "[::1]" not in policy  # CSP has no IPv6 literal: Chromium refused it and logged an error each load
        assert response.headers["referrer-policy"] == "no-referrer"
        assert response.headers["x-content-type-options"] == "nosniff"
        framers = policy.split("frame-ancestors ", 1)[1].split(";")[0]
        if url == f"/?token={TOKEN}":  # a notebook's frame names the token: loopback pages may frame it
            assert framers == "http://localhost:* http://127.0.0.1:* https://localhost:* https://127.0.0.1:*"
            assert "x-frame-options" not in response.headers
        else:  # opened by its cookie: framed by no page (another port of 127.0.0.1 is the same site)
            assert framers == "'none'" and response.headers["x-frame-options"] == "DENY", url


def test_the_page_can_ask_whether_its_token_is_refused(scene_path):
    """A socket refused before its upgrade reaches a browser as close code 1006, as a server that is down does;
    /access tells the two apart: 403 for a token or cookie the server refuses, 204 for a good one."""
    client = client_for(scene_path)
    assert client.get("/access").status_code == 403 and client.get("/access?token=wrong").status_code == 403
    assert client.get(f"/access?token={TOKEN}").status_code == 204
    assert client.get(f"/?token={TOKEN}").status_code == 200
    assert client.get("/access").status_code == 204  # the cookie the page's first load set


# ---------------------------------------------------------------- the scene schema's messages


def test_a_bad_value_gets_the_clis_one_line_message(scene_path, monkeypatch):
    monkeypatch.delenv("RAYCAST_PHONG_DEBUG", raising=False)
    cli = CliRunner().invoke(cli_app, ["render", str(scene_path), "--set", "render.samples=99", "-o",
                                       str(scene_path.with_suffix(".png"))])
    assert cli.exit_code == 2
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "settings": {"render.samples": 99}}))
        answer = json.loads(ws.receive_text())
    assert answer["type"] == "error" and answer["id"] == 1
    assert f"error: {answer['message']}" == cli.output.strip()
    assert "\n" not in answer["message"] and "render.samples" in answer["message"] and "≤ 16" in answer["message"]


@pytest.mark.parametrize(("settings", "says"), [
    ({"objects.0.path": "/etc/passwd"}, "does not change file paths"),
    ({"output.path": "x.png"}, "does not change file paths"),
    ({"materials.red.kd_map": "/etc/passwd"}, "materials.red.kd_map: the view does not change file paths"),
    ({"materials.red.ke_map.path": "x.png"}, "materials.red.ke_map.path: the view does not change file paths"),
    ({"render.width": 16384, "render.height": 16384}, "rays per frame"),
    ({"render.width": 1920, "render.height": 1080, "render.samples": 5}, "1920×1080 pixels × 5² samples"),  # 5² > 16
    ({"render..width": 3}, "not a key path"),
    ({"materials.red.shininess": "__import__('os')"}, "materials.red.shininess"),
])
def test_page_values_are_data_for_the_schema_only(scene_path, settings, says):
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 7, "settings": settings}))
        answer = json.loads(ws.receive_text())
        assert answer["type"] == "error" and says in answer["message"], answer
        ws.send_text("not json")
        assert "not JSON" in json.loads(ws.receive_text())["message"]
        for malformed in ({"settings": [1, 2]}, {"compare": "x"}, {"quality": "best"}):
            ws.send_text(json.dumps({"type": "render", "id": 8, **malformed}))
            answer = json.loads(ws.receive_text())
            assert answer["type"] == "error" and "internal" not in answer["message"], (malformed, answer)


@pytest.mark.timeout(120)  # a message the server never answers (a RecursionError taken for a closed page) hangs
def test_numbers_and_nesting_past_the_parsers_limits_are_one_line_and_the_socket_stays(scene_path):
    """A 5000-digit `id` or setting, and a message or loaded scene nested 20000 deep, dropped the socket with a
    server traceback (ValueError: Python's 4300-digit limit; RecursionError): now the message's one line, and
    the same socket goes on to render."""
    digits = "1" * 5000
    nested = "[" * 20_000 + "]" * 20_000
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        for text in ('{"type": "render", "id": ' + digits + "}",
                     '{"type": "render", "id": 1, "settings": {"render.width": ' + digits + "}}",
                     '{"type": "render", "id": ' + nested + "}",
                     json.dumps({"type": "load", "id": 2, "name": "deep.toml", "text": "a = " + nested}),
                     json.dumps({"type": "load", "id": 3, "name": "big.toml", "text": "a = " + digits})):
            ws.send_text(text)
            answer = json.loads(ws.receive_text())
            assert answer["type"] == "error" and "\n" not in answer["message"], answer
            assert "nested too deep" in answer["message"] or "more digits" in answer["message"], answer
        ws.send_text(json.dumps({"type": "render", "id": 4, "settings": {"render.shading": "flat"}}))
        receive_frame(ws)


@contextmanager
def served_socket(scene_path: Path, monkeypatch):
    """A socket to a real uvicorn view of `scene_path` (its own message size limits), without the kernels' warm-up;
    recv(timeout=…) fails rather than waits when the server drops it."""
    from websockets.sync.client import connect as socket_to

    from raycast_phong.tools.view import running, server
    monkeypatch.setattr(server, "warm", lambda source: None)
    with running(scene_path) as url:
        origin = url.split("/?", 1)[0]
        address = origin.replace("http://", "ws://") + "/socket?token=" + url.split("token=", 1)[1]
        with socket_to(address, origin=origin, max_size=None) as ws:
            yield ws


def test_a_loaded_file_naming_a_symlink_loop_is_one_line_and_the_socket_stays(scene_path, monkeypatch):
    """A texture path of an opened file that links to itself: Path.resolve raised RuntimeError (Python 3.11) and
    the socket was dropped without a word; now the line names the key and the path, and the socket goes on."""
    (scene_path.parent / "loop.png").symlink_to("loop.png")
    text = scene_path.read_text().replace("[materials.red]\n", '[materials.red]\nkd_map = "loop.png"\n')
    with served_socket(scene_path, monkeypatch) as ws:
        ws.recv(timeout=30)
        ws.send(json.dumps({"type": "load", "id": 1, "name": "loop.toml", "text": text}))
        answer = json.loads(ws.recv(timeout=30))
        assert answer["type"] == "error" and answer["id"] == 1, answer
        assert answer["message"] == "loop.toml: materials.red.kd_map.path: loop.png: a symlink loop", answer
        ws.send(json.dumps({"type": "load", "id": 2, "name": "same.toml", "text": scene_path.read_text()}))
        assert json.loads(ws.recv(timeout=30)) == {"type": "loaded", "id": 2, "settings": {}}


def test_a_scene_the_page_opens_fits_the_socket_up_to_the_documented_size(scene_path, monkeypatch):
    """docs/view.md: a scene file the page opens is at most 60,000 bytes. A 57 kB one, its quotes and newlines
    escaped as JSON, was cut by the socket's 64 KiB (closed, 1009, nothing said); now any text of that size fits
    escaped (6 bytes a control character at worst), a larger scene or message is one line, and the socket stays."""
    from raycast_phong.tools.view import session
    note = '# a "quoted" note\n'
    quoted = scene_path.read_text() + note * ((57_000 - len(scene_path.read_text())) // len(note))
    worst = "\x01" * session.MAX_SCENE_BYTES  # no scene, but as large as the page lets through, escaped 6×
    sent = {"quoted.toml": quoted, "worst.toml": worst, "big.toml": quoted + note * 250}
    with served_socket(scene_path, monkeypatch) as ws:
        assert json.loads(ws.recv(timeout=30))["limits"] == {"scene_bytes": 60_000, "message_bytes": 1 << 19}
        replies = {}
        for request_id, (name, text) in enumerate(sent.items()):
            ws.send(json.dumps({"type": "load", "id": request_id, "name": name, "text": text}))
            replies[name] = json.loads(ws.recv(timeout=30))
        ws.send(json.dumps({"type": "render", "id": 9, "pad": "x" * session.MAX_MESSAGE_BYTES}))
        too_large = json.loads(ws.recv(timeout=30))
        ws.send(json.dumps({"type": "load", "id": 10, "name": "same.toml", "text": scene_path.read_text()}))
        assert json.loads(ws.recv(timeout=30))["type"] == "loaded"
    assert len(json.dumps({"text": quoted})) > 1 << 16 and len(json.dumps({"text": worst})) > 6 * 60_000
    assert replies["quoted.toml"] == {"type": "loaded", "id": 0, "settings": {}}, replies
    assert replies["worst.toml"]["type"] == "error" and "not a TOML scene" in replies["worst.toml"]["message"]
    assert replies["big.toml"]["message"] == (f"big.toml: {len(sent['big.toml']):,} bytes; a scene file the page "
                                              "opens is at most 60,000 bytes"), replies
    assert too_large["type"] == "error" and re.fullmatch(r"message of [\d,]+ bytes; allowed: at most 524,288",
                                                         too_large["message"]), too_large


def test_the_view_refuses_more_lights_than_it_allows_in_one_line(scene_path, tmp_path):
    """2,500 lights set from the page held a render thread over a minute at the largest frame, with no limit said:
    the view allows MAX_VIEW_LIGHTS (63, what global mode can), and more is one line naming the count and the
    range, from a page setting or in the scene the view starts with; as many as allowed render."""
    from raycast_phong.tools.view.server import MAX_VIEW_LIGHTS, ViewError
    assert MAX_VIEW_LIGHTS == 63
    light = {"position": [3, 4, 6]}
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "settings": {"lights": [light] * 2500}}))
        answer = json.loads(ws.receive_text())
        assert answer == {"type": "error", "id": 1, "message": f"{scene_path}: lights: 2,500 lights; allowed: 0 to "
                          "63 in the view; render it with `raycast-phong render` instead"}, answer
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "draft",
                                 "settings": {"lights": [light] * MAX_VIEW_LIGHTS}}))
        assert receive_frame(ws)[0]["id"] == 2
    many = write_tiny_scene(tmp_path, 16, 12, "[[lights]]\nposition = [0, 0, 5]\n" * MAX_VIEW_LIGHTS)
    with pytest.raises(ViewError, match=r"tiny.toml: lights: 64 lights; allowed: 0 to 63 in the view"):
        open_scene(many)


def test_a_path_past_the_key_names_is_caught_in_the_validated_scene(scene_path, monkeypatch):
    """The second guard: were a key that names a file missed by PATH_KEYS, the validated scene's named_files
    still differ from the source's, and the settings are refused before any file is opened."""
    from raycast_phong.tools.view import server
    source = open_scene(scene_path)
    monkeypatch.setattr(server, "PATH_KEYS", server.re.compile("(?!)"))  # matches no key
    for key, says in (("materials.red.kd_map", "materials.red.kd_map.path"),
                      ("materials.red.ke_map.path", "materials.red.ke_map.path"),
                      ("materials.blue.ka_map", "materials.blue.ka_map.path")):
        with pytest.raises(server.ViewError, match=rf": {says}: the view does not change file paths"):
            server.scene_with(source, {key: "/etc/passwd"})
    assert server.scene_with(source, {"materials.red.shininess": 5.0}).materials["red"].shininess == 5.0


def test_the_page_cannot_read_or_probe_files_through_textures(tmp_path):
    """A texture path from the page is refused with the same line whatever is at it (an image outside the
    scene's folder, nothing, a FIFO that would block the worker), so nothing is read, waited on or told."""
    (tmp_path / "scene").mkdir()
    scene_path = write_tiny_scene(tmp_path / "scene", 16, 12)
    outside = tmp_path / "photo.png"
    rp.write_image(outside, np.full((4, 4, 3), 0.5, np.float32))
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    messages = []
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        for target in (outside, tmp_path / "missing.png", fifo):
            for key in ("materials.red.kd_map", "materials.red.kd_map.path"):
                ws.send_text(json.dumps({"type": "render", "id": 9, "settings": {key: str(target)}}))
                answer = json.loads(ws.receive_text())
                assert answer["type"] == "error", answer
                messages.append(answer["message"].replace(str(target), "PATH"))
        ws.send_text(json.dumps({"type": "render", "id": 10, "settings": {"render.shading": "flat"}}))
        receive_frame(ws)  # the worker is free: nothing waited on the FIFO
    assert len(set(messages[0::2])) == 1 and len(set(messages[1::2])) == 1, messages
    assert "PATH" not in messages[0]  # the line does not even repeat the path


# ---------------------------------------------------------------- frames


SHADING = {"render.shading": "flat", "render.specular": "blinn", "materials.red.shininess": 12.5,
           "lights.0.diffuse": [0.2, 0.9, 0.4]}


def test_a_frame_is_the_png_of_render_with_the_same_settings(scene_path, tmp_path):
    overrides = ["render.shading=\"flat\"", "render.specular=\"blinn\"", "materials.red.shininess=12.5",
                 "lights.0.diffuse=[0.2, 0.9, 0.4]"]
    expected = rendered_png(rp.load_scene(scene_path, overrides))
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "full", "settings": SHADING}))
        header, parts = receive_frame(ws)
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "draft", "settings": SHADING}))
        draft, draft_parts = receive_frame(ws)
    np.testing.assert_array_equal(decode_png(parts["a"], tmp_path), expected)
    stats = header["stats"]["a"]
    assert (stats["width"], stats["height"], stats["rays"]) == (64, 48, 64 * 48)
    assert stats["rays_per_second"] > 0 and stats["frame"] > 0
    assert {"shadow_rays", "supersampling"} <= {stage["name"] for stage in stats["left_out"]}
    # Dragging: a quarter of the pixels, the same camera.
    draft_scene = rp.load_scene(scene_path, [*overrides, "render.width=32", "render.height=24"])
    np.testing.assert_array_equal(decode_png(draft_parts["a"], tmp_path), rendered_png(draft_scene))
    assert draft["stats"]["a"]["rays"] == 32 * 24


def test_compare_sends_both_frames_and_their_difference(scene_path, tmp_path):
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "settings": {"render.shading": "flat"},
                                 "compare": {"render.shading": "phong"}}))
        header, parts = receive_frame(ws)
    flat = rp.render(rp.load_scene(scene_path, ["render.shading=\"flat\""])).image
    phong = rp.render(rp.load_scene(scene_path, ["render.shading=\"phong\""])).image
    np.testing.assert_array_equal(decode_png(parts["b"], tmp_path), to_8bit(phong))
    assert header["difference"]["max"] == pytest.approx(float(np.abs(flat - phong).max()), rel=1e-6)
    assert decode_png(parts["heat"], tmp_path).shape == (48, 64, 3)


def test_the_three_models_of_a_in_one_frame(scene_path, tmp_path):
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "models": True, "settings": {"render.specular": "blinn"},
                                 "compare": {"render.shading": "flat"}}))  # models wins over a comparison
        header, parts = receive_frame(ws)
        ws.send_text(json.dumps({"type": "save", "id": 2, "what": "toml", "side": "b", "settings": {}}))
        saved, _ = unpack(ws.receive_bytes())
        ws.send_text(json.dumps({"type": "save", "id": 3, "what": "toml", "side": "c", "settings": {}}))
        refused = json.loads(ws.receive_text())
    assert sorted(parts) == ["a", "b", "c"] and "difference" not in header
    for name, model in zip("abc", ("flat", "gouraud", "phong")):
        scene = rp.load_scene(scene_path, [f'render.shading="{model}"', f'objects.0.shading="{model}"',
                                           'render.specular="blinn"'])
        np.testing.assert_array_equal(decode_png(parts[name], tmp_path), rendered_png(scene))
    assert saved["filename"] == "tiny-view-B.toml"
    assert refused["type"] == "error" and "allowed: 'a' or 'b'" in refused["message"]


def test_an_edited_scene_file_is_reloaded_and_a_broken_one_kept_out(scene_path, tmp_path, monkeypatch):
    from raycast_phong.tools.view import session
    monkeypatch.setattr(session, "WATCH_EVERY", 0.05)
    text = scene_path.read_text()
    client = client_for(scene_path)
    with connect(client) as ws:
        ws.receive_text()
        scene_path.write_text(text.replace("ambient = [0.1, 0.1, 0.1]", "ambient = [0.5, 0.2, 0.1]"))
        hello = json.loads(ws.receive_text())
        assert hello["type"] == "hello" and hello["reloaded"] and hello["scene"]["ambient"] == [0.5, 0.2, 0.1]
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "full", "settings": SHADING}))
        _, parts = receive_frame(ws)
        edited = rp.load_scene(scene_path, [f"{k}={json.dumps(v)}" for k, v in SHADING.items()])
        np.testing.assert_array_equal(decode_png(parts["a"], tmp_path), rendered_png(edited))
        scene_path.write_text(text.replace("subdivisions = 1", "subdivisions = -1"))  # invalid: refused, kept out
        error = json.loads(ws.receive_text())
        assert error["type"] == "error" and "objects.0.subdivisions" in error["message"]
        assert "\n" not in error["message"] and "keeps the scene as it was" in error["message"]
        assert error["file"] is True  # the page keeps it on screen until the file is valid again
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "full", "settings": SHADING}))
        _, parts = receive_frame(ws)
        np.testing.assert_array_equal(decode_png(parts["a"], tmp_path), rendered_png(edited))  # the last good one
        with connect(client) as late:  # a page opened meanwhile is told too
            assert json.loads(late.receive_text())["problem"] == error["message"]
        scene_path.write_text(text)
        fixed = json.loads(ws.receive_text())
        for _ in range(3):  # the watcher may catch the file between its truncation and its write: one more error
            if fixed["type"] == "hello":
                break
            fixed = json.loads(ws.receive_text())
        assert fixed["scene"]["ambient"] == [0.1, 0.1, 0.1] and fixed["problem"] is None


@contextmanager
def draft_held(scene_path, settings: dict | None = None):
    """A page whose draft 1 (with `settings`) is rendering, held until the `release` yielded beside the socket is
    set (up to 60 s); later frames render at once: requests sent meanwhile queue behind it."""
    started, release = threading.Event(), threading.Event()

    def held_render(session, scene, **options):
        if not started.is_set():
            started.set()
            release.wait(60)
        return session_render(session, scene, **options)

    with connect(client_for(scene_path, render=held_render)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "draft", "settings": settings or {}}))
        assert started.wait(60)
        yield ws, release


def test_latest_wins_while_a_render_runs(scene_path):
    """Requests that arrive while a render runs replace one another: only the newest is rendered."""
    with draft_held(scene_path) as (ws, release):
        for request_id in (2, 3, 4):
            ws.send_text(json.dumps({"type": "render", "id": request_id, "quality": "draft"}))
        dropped = [json.loads(ws.receive_text()) for _ in range(2)]
        release.set()
        first, _ = receive_frame(ws)
        last, _ = receive_frame(ws)
    assert dropped == [{"type": "dropped", "id": 2}, {"type": "dropped", "id": 3}]
    assert (first["id"], last["id"]) == (1, 4)


def test_a_waiting_full_request_replaced_by_a_newer_one_is_told_dropped(scene_path):
    """Two full requests (2, 3) sent while a draft (1) renders: the newer replaces the waiting one, and the page
    is told that 2 was dropped (it stops waiting for it), as for drafts. Catches a full request replacing the
    waiting full one without a word."""
    with draft_held(scene_path) as (ws, release):
        for request_id in (2, 3):
            ws.send_text(json.dumps({"type": "render", "id": request_id, "quality": "full"}))
        told = json.loads(ws.receive_text())
        while told["type"] == "progress":
            told = json.loads(ws.receive_text())
        release.set()
        frames = []
        while not frames or frames[-1]["id"] != 3:
            message = ws.receive()
            if message.get("bytes") is not None:
                frames.append(unpack(message["bytes"])[0])
    assert told == {"type": "dropped", "id": 2}
    assert [header["id"] for header in frames] == [3]


def test_a_release_is_never_coalesced_away_by_the_next_strokes_drafts(scene_path, tmp_path):
    """Strokes back to back (issue 35): a release's full frame (2) sent while a draft (1) renders, then the next
    stroke's drafts (3, 4) at once. Latest wins among the drafts only: the running draft is cancelled (its state
    is stale), the full frame is rendered next, with the settings it was sent with, then the newest draft; draft
    3 is dropped."""
    light = lambda x: {"lights.0.position": [x, 2, 3]}
    with draft_held(scene_path, light(0)) as (ws, release):
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "full", "settings": light(1)}))
        for request_id in (3, 4):
            ws.send_text(json.dumps({"type": "render", "id": request_id, "quality": "draft",
                                     "settings": light(request_id)}))
        dropped = json.loads(ws.receive_text())
        release.set()
        told, frames = [], []
        while len(frames) < 2:
            message = ws.receive()
            if message.get("text") is not None:
                told.append(json.loads(message["text"]))
            else:
                frames.append(unpack(message["bytes"]))
    assert dropped == {"type": "dropped", "id": 3}
    assert [m for m in told if m["type"] != "progress"] == [{"type": "cancelled", "id": 1, "done": 0, "of": 1}]
    assert [(header["id"], header["quality"]) for header, _ in frames] == [(2, "full"), (4, "draft")]
    full = rp.load_scene(scene_path, ["lights.0.position=[1, 2, 3]"])
    np.testing.assert_array_equal(decode_png(frames[0][1]["a"], tmp_path), rendered_png(full))


def test_a_draft_does_not_cancel_a_releases_frame_only_its_refinement(scene_path, monkeypatch):
    """A draft sent while a release's first full-size frame renders (one sample a pixel: the full frame itself, 5
    bands of 51 rows) waits for it: that frame is not cancelled, it is sent, and the draft follows."""
    from raycast_phong.renderer import prepare
    running, go = threading.Event(), threading.Event()
    band = prepare.TileWork.__call__

    def held_band(tile, rows):
        if tile.film.rgb.shape[1] == 640:  # the full frame's first bands wait until the draft has been sent
            running.set()
            go.wait(30)
        return band(tile, rows)
    monkeypatch.setattr(prepare.TileWork, "__call__", held_band)
    settings = {"render.width": 640, "render.height": 240}
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "full", "settings": settings}))
        assert running.wait(60)
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "draft", "settings": settings}))
        time.sleep(0.2)  # the draft is queued (or, on the old server, has cancelled the frame) before it goes on
        go.set()
        full, _ = receive_frame(ws)
        draft, _ = receive_frame(ws)
    assert (full["id"], full["quality"], full["stats"]["a"]["width"]) == (1, "full", 640)
    assert (draft["id"], draft["quality"]) == (2, "draft")


def test_a_frame_asked_as_rgba_is_the_pngs_pixels_raw(scene_path, tmp_path):
    """The page asks for drafts as raw RGBA (painted into a canvas, nothing to decode), and full frames too from
    this machine: the PNG's 8-bit values with an opaque alpha, rows top first; a full frame asked as PNG is the
    PNG render writes; another format is refused."""
    settings = {"lights.0.position": [0, 1, 4]}
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        frames = {}
        for request_id, quality, pixels in ((1, "draft", "png"), (2, "draft", "rgba"), (3, "full", "rgba"),
                                            (5, "full", "png")):
            ws.send_text(json.dumps({"type": "render", "id": request_id, "quality": quality, "settings": settings,
                                     "pixels": pixels}))
            frames[request_id] = receive_frame(ws)
        ws.send_text(json.dumps({"type": "render", "id": 4, "quality": "draft", "pixels": "jpeg"}))
        refused = json.loads(ws.receive_text())
    png, full_png = frames[1][1], frames[5][1]
    assert [frames[k][0]["pixels"] for k in (1, 2, 3, 5)] == ["png", "rgba", "rgba", "png"]
    for (header, pixels), reference in ((frames[2], png), (frames[3], full_png)):
        height, width = header["stats"]["a"]["height"], header["stats"]["a"]["width"]
        rgba = np.frombuffer(pixels["a"], np.uint8).reshape(height, width, 4)
        np.testing.assert_array_equal(rgba[..., :3], decode_png(reference["a"], tmp_path))
        assert (rgba[..., 3] == 255).all()
    assert full_png["a"].startswith(b"\x89PNG")
    scene = frame_of(scene_with(open_scene(scene_path), settings))
    np.testing.assert_array_equal(decode_png(full_png["a"], tmp_path), rendered_png(scene))
    assert refused == {"type": "error", "id": 4, "message": "pixels: 'jpeg'; allowed: 'png' or 'rgba'"}


def test_exact_errors_follow_a_full_frame_of_an_analytic_scene(scene_path):
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 5, "quality": "full", "reference": True}))
        receive_frame(ws)
        errors = json.loads(ws.receive_text())
    scene = rp.load_scene(scene_path)
    measured = accuracy.measured(scene, rp.render(scene), "analytic").errors
    assert errors["type"] == "errors" and errors["id"] == 5
    assert errors["rmse"] == pytest.approx(measured.rmse) and errors["max_error"] == pytest.approx(measured.max_error)


def test_the_exact_reference_waits_until_the_page_rests(scene_path):
    """A drag keeps one draft in flight and none waiting: the exact errors of the full frame before it are not
    computed while the drag goes on (they used to start REFERENCE_REST after it, mid-drag, on the server's CPU),
    and follow once the page rests."""
    from raycast_phong.tools.view.session import REFERENCE_REST
    seen = []
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "full", "reference": True}))
        receive_frame(ws)
        request_id, end = 1, time.monotonic() + 4 * REFERENCE_REST
        while time.monotonic() < end:  # the drag: the next draft goes when the last is answered
            request_id += 1
            ws.send_text(json.dumps({"type": "render", "id": request_id, "quality": "draft",
                                     "settings": {"lights.0.position": [request_id / 100, 2, 3]}}))
            message = ws.receive()
            while message.get("bytes") is None:
                seen.append(json.loads(message["text"])["type"])
                message = ws.receive()
            time.sleep(0.02)
        assert "errors" not in seen and request_id > 5, seen
        errors = json.loads(ws.receive_text())  # the page rests
    assert errors["type"] == "errors" and errors["id"] == 1


def test_a_slow_page_does_not_hold_another_pages_frames(scene_path):
    """Each page renders on its own thread: while one page's frame is held, another page gets its frames."""
    started, release, finished = threading.Event(), threading.Event(), threading.Event()

    def held_render(session, scene, **options):
        if scene.render.width == 31:  # the slow page's draft (of 61 pixels across)
            started.set()
            release.wait(30)
            finished.set()
        return session_render(session, scene, **options)

    client = client_for(scene_path, render=held_render)
    try:
        with connect(client) as slow, connect(client) as other:
            slow.receive_text()
            other.receive_text()
            slow.send_text(json.dumps({"type": "render", "id": 1, "quality": "draft",
                                       "settings": {"render.width": 61}}))
            assert started.wait(60)
            other.send_text(json.dumps({"type": "render", "id": 1, "quality": "draft"}))
            header, _ = receive_frame(other)  # while the slow page's frame is still held
            assert header["stats"]["a"]["width"] == 32 and not finished.is_set()
            release.set()
            assert receive_frame(slow)[0]["stats"]["a"]["width"] == 31  # its draft: half of 61, rounded up
    finally:
        release.set()


def test_the_exact_reference_runs_at_the_lowest_priority():
    """Linux schedules threads one by one: a page's reference thread at nice 19 leaves the cores to the frames;
    its render thread keeps the server's priority."""
    from raycast_phong.tools.view.server import Client
    page = Client()
    nice = lambda: os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    try:
        assert page.references.submit(nice).result(30) == 19
        assert page.executor.submit(nice).result(30) == os.getpriority(os.PRIO_PROCESS, 0)
    finally:
        page.references.shutdown()
        page.executor.shutdown()


def test_a_saved_scene_renders_to_the_frame_shown(scene_path, tmp_path):
    settings = {**SHADING, "lights.0.position": [-1.5, 0.5, 2.0], "objects.0.subdivisions": 3}
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "settings": settings}))
        _, frame = receive_frame(ws)
        for what in ("toml", "exr", "png"):
            ws.send_text(json.dumps({"type": "save", "id": 2, "what": what, "settings": settings}))
            header, parts = unpack(ws.receive_bytes())
            assert header["type"] == "saved" and header["filename"] == f"tiny-view-A.{what}"
            (tmp_path / header["filename"]).write_bytes(parts["file"])
    saved = rp.load_scene(tmp_path / "tiny-view-A.toml")
    np.testing.assert_array_equal(rendered_png(saved), decode_png(frame["a"], tmp_path))
    np.testing.assert_array_equal(rp.read_image(tmp_path / "tiny-view-A.exr")[0], rp.render(saved).image)
    assert (tmp_path / "tiny-view-A.png").read_bytes() == frame["a"]  # the same bytes as the frame shown


# ---------------------------------------------------------------- the command


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM])
def test_view_command_prints_a_url_whose_token_is_required(scene_path, tmp_path, stop):
    """...and stops on Ctrl-C or `kill` with 128 + the signal's number and one line saying so, as batch does (it
    exited 0, as if it had finished)."""
    command = [sys.executable, "-c", "from raycast_phong.cli import app; app()", "view", str(scene_path),
               "--port", "0",
               "--no-browser"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               cwd=Path(__file__).resolve().parents[2],
                               env={**os.environ, "XDG_STATE_HOME": str(tmp_path)})  # its kept token
    try:
        line = process.stdout.readline()
        assert line.startswith("raycast-phong view: open http://127.0.0.1:"), line + process.stderr.read()
        url = line.split("open ", 1)[1].strip()
        assert "token=" in url and len(url.split("token=", 1)[1]) >= 40  # token_urlsafe(32): 43 characters
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(url.split("?", 1)[0], timeout=30)
        assert refused.value.code == 403
    finally:
        process.send_signal(stop)
        try:
            process.wait(30)
        except subprocess.TimeoutExpired:
            process.kill()
            raise
    errors = process.stderr.read()
    assert process.returncode == 128 + stop, errors
    assert errors.strip().splitlines()[-1] == f"raycast-phong view: stopped by {stop.name}", errors


def test_the_server_prepares_every_kernel_the_page_can_ask_for_and_says_so(scene_path, monkeypatch):
    from raycast_phong.renderer import frame
    from raycast_phong.tools.view import server
    warmed = []
    monkeypatch.setattr(frame, "warm_kernels", lambda reals: warmed.append(set(reals)))
    server.warm(open_scene(scene_path))
    assert warmed == [{np.float32, np.float64}]  # both precisions (the tile kernel holds global mode's shadow rays)
    release = threading.Event()
    monkeypatch.setattr(server, "warm", lambda source: release.wait(60))
    client = client_for(scene_path)
    with connect(client) as ws:
        assert json.loads(ws.receive_text())["warming"] is True  # the page shows "preparing the renderer"
    release.set()
    client.app.state.warming.result(60)
    with connect(client) as ws:
        assert json.loads(ws.receive_text())["warming"] is False


def test_a_full_frame_reports_its_progress(scene_path):
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 7, "quality": "full"}))
        message = ws.receive()
        while "text" in message:  # progress messages come before the frame
            progress = json.loads(message["text"])
            assert progress["type"] == "progress" and progress["id"] == 7 and 0 <= progress["done"] < 1
            message = ws.receive()
        assert unpack(message["bytes"])[0]["id"] == 7


def test_a_saved_scene_file_loads_back_as_the_settings_that_make_it(scene_path):
    from raycast_phong.io.scene_toml import scene_toml
    changes = {"render.shading": "flat", "lights.0.position": [1.0, -2.0, 3.5], "materials.red.shininess": 10.0,
               "camera.look_at": [0.25, 0.0, 0.0]}
    from raycast_phong.tools.view.server import ViewError, scene_with, settings_from
    source = open_scene(scene_path)
    text = scene_toml(scene_with(source, changes))
    assert settings_from(source, text, "saved.toml") == changes
    assert settings_from(source, json.dumps(rp.load_scene(scene_path).model_dump(mode="json", exclude={"folder"})),
                         "same.json") == {}
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "load", "id": 3, "name": "../../saved.toml", "text": text}))
        assert json.loads(ws.receive_text()) == {"type": "loaded", "id": 3, "settings": changes}
        refusals = {"x = [": "not a TOML scene",
                    text + "\n[[lights]]\nposition = [0, 0, 5]\n": "2 lights, this view's scene has 1",
                    text.replace("shininess = 10.0", "shininess = -1.0"): "materials.red.shininess"}
        for bad, says in refusals.items():
            ws.send_text(json.dumps({"type": "load", "id": 4, "name": "saved.toml", "text": bad}))
            reply = json.loads(ws.receive_text())
            assert reply["type"] == "error" and says in reply["message"] and "\n" not in reply["message"], reply
    # A view of a mesh file: the saved file names it by its absolute path, which is the same file; another is not.
    mesh = Path(__file__).resolve().parents[2] / "scenes" / "meshes" / "torus_knot.ply"
    source = open_scene(mesh)
    text = scene_toml(scene_with(source, {"render.shading": "flat"}))
    assert settings_from(source, text, "knot.toml") == {"render.shading": "flat"}
    with pytest.raises(ViewError, match=r"objects.0.path is .*painted_knot.ply, not this view's torus_knot.ply"):
        settings_from(source, text.replace("torus_knot.ply", "painted_knot.ply"), "knot.toml")


def test_the_token_is_kept_between_runs_in_a_private_folder(tmp_path, monkeypatch):
    from raycast_phong.tools.view import remembered_token
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    first = remembered_token()
    assert len(first) >= 40 and remembered_token() == first  # a restarted server accepts the open pages
    folder = tmp_path / "raycast-phong"
    assert folder.stat().st_mode & 0o777 == 0o700
    assert (folder / "view-token").read_text().strip() == first
    (folder / "view-token").write_text("short\n")  # not a token: replaced
    replaced = remembered_token()
    assert replaced != first and len(replaced) >= 40 and remembered_token() == replaced
    folder.chmod(0o755)  # others can read the folder: its token is not reused, and none is written there
    assert remembered_token() != replaced
    assert (folder / "view-token").read_text().strip() == replaced


def test_ctrl_c_during_a_long_render_stops_the_command_at_once(tmp_path):
    from websockets.sync.client import connect as ws_connect
    path = write_tiny_scene(tmp_path, 64, 48)
    command = [sys.executable, "-c", "from raycast_phong.cli import app; app()", "view", str(path), "--port", "0",
               "--no-browser"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env={**os.environ, "XDG_STATE_HOME": str(tmp_path)})
    try:
        url = process.stdout.readline().split("open ", 1)[1].strip()
        origin = url.split("/?", 1)[0]
        socket_url = origin.replace("http://", "ws://") + "/socket?token=" + url.split("token=", 1)[1]
        with ws_connect(socket_url, origin=origin, max_size=None) as ws:
            ws.recv()  # hello
            # The largest frame the view renders (1920 × 1080 × 4² rays, float64, shadow rays): seconds.
            big = {"render.width": 1920, "render.height": 1080, "render.samples": 4, "render.precision": "float64",
                   "render.mode": "global"}
            ws.send(json.dumps({"type": "render", "id": 1, "quality": "full", "settings": big}))
            while json.loads(ws.recv(timeout=120)).get("type") != "progress":  # the frame is being rendered
                pass
            process.send_signal(signal.SIGINT)
            stopped = time.perf_counter()
            time.sleep(0.2)
            process.send_signal(signal.SIGINT)  # an impatient second Ctrl-C
            process.wait(30)
            waited = time.perf_counter() - stopped
    finally:
        if process.poll() is None:
            process.kill()
    errors = process.stderr.read()
    # 128 + SIGINT, rendering or not; or killed by the second Ctrl-C while the interpreter tears down (app() here, not
    # the console script's quick exit): a shell says 130 for both
    assert process.returncode in (130, -signal.SIGINT) and "Traceback" not in errors, errors
    assert errors.strip().splitlines()[-1] == "raycast-phong view: stopped by SIGINT", errors
    assert waited < 3, f"Ctrl-C took {waited:.1f} s"


def test_view_command_refuses_a_bad_scene_in_one_line(tmp_path, monkeypatch):
    monkeypatch.delenv("RAYCAST_PHONG_DEBUG", raising=False)
    bad = write_tiny_scene(tmp_path, 64, 48, extra="[output]\npath = 'x.jpg'\n")
    result = CliRunner().invoke(cli_app, ["view", str(bad), "--no-browser", "--port", "0"])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and "output.path" in result.output


def test_view_command_warns_when_not_bound_to_loopback(monkeypatch):
    import raycast_phong.tools.view as live
    monkeypatch.setattr(live, "serve", lambda *args, **kwargs: None)  # only the warning is under test
    result = CliRunner().invoke(cli_app, ["view", "--host", "0.0.0.0", "--no-browser"])
    assert result.exit_code == 0 and "reachable from other machines" in result.output


def test_view_command_gives_its_max_memory_to_the_server_and_refuses_a_bad_one(monkeypatch):
    """`view --max-memory 500M` reaches serve() as bytes (create_app shares it between the frames); a size that is
    none is one line naming the option, exit 2, before any server starts."""
    import raycast_phong.tools.view as live
    given = {}
    monkeypatch.setattr(live, "serve", lambda *args, **kwargs: given.update(kwargs))
    result = CliRunner().invoke(cli_app, ["view", "--max-memory", "500M", "--no-browser"])
    assert result.exit_code == 0 and given["max_memory"] == 500 << 20, (result.output, given)
    given.clear()
    result = CliRunner().invoke(cli_app, ["view", "--max-memory", "lots", "--no-browser"])
    assert result.exit_code == 2 and "--max-memory" in result.output and given == {}, result.output
    assert result.output.strip().count("\n") == 0


@pytest.mark.slow
def test_benchmark_script_runs_in_a_reduced_form():
    """bench_view.py is not a timed test; this keeps the script working (tiny frame, few requests)."""
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_view.py"), "--size", "64x36",
                           "--steps", "2", "--rate", "20", "--seconds", "0.5"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert "at 64×36 (draft 32×18)" in done.stdout and "step, draft: change→image" in done.stdout
    assert "10 moves at 20 Hz" in done.stdout


@pytest.mark.slow
def test_the_servers_cpu_benchmark_runs_in_a_reduced_form():
    """bench_view_cpu.py (the server's CPU a frame, from /proc) is not a timed test; this keeps it working."""
    if not Path("/proc/self/stat").exists():
        pytest.skip("reads /proc")
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_view_cpu.py"), "--size", "64x36",
                           "--frames", "3"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "light moved, draft" in done.stdout and "orbit, draft" in done.stdout and "ms a frame" in done.stdout


def test_the_view_command_gives_numpys_blas_one_thread(scene_path):
    """The frames run on the server's band threads; OpenBLAS's own threads spun after each product at the server's
    priority (the exact reference's, which itself runs at nice 19). `view` starts numpy with one BLAS thread unless
    OPENBLAS_NUM_THREADS says otherwise; asked of the OpenBLAS numpy loaded, when the server would start serving."""
    code = f"""
import ctypes, os, sys
import uvicorn
def run(self, sockets=None):
    import numpy
    path = next((line.split()[-1] for line in open('/proc/self/maps') if 'openblas' in line.lower()), None)
    asked = [getattr(ctypes.CDLL(path), name, None) for name in
             ('scipy_openblas_get_num_threads64_', 'openblas_get_num_threads64_', 'openblas_get_num_threads')]
    print('BLAS threads', next(f() for f in asked if f is not None) if path else 'no OpenBLAS')
uvicorn.Server.run = run
from raycast_phong.cli import app
sys.argv = ['raycast-phong', 'view', {str(scene_path)!r}, '--port', '0', '--no-browser', '-q']
app()
"""
    for chosen, expected in ((None, "1"), *((("2", "2"),) if (os.cpu_count() or 1) >= 2 else ())):
        env = {key: value for key, value in os.environ.items() if key != "OPENBLAS_NUM_THREADS"}
        if chosen:
            env["OPENBLAS_NUM_THREADS"] = chosen
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
        line = next((line for line in done.stdout.splitlines() if line.startswith("BLAS threads")), done.stderr)
        if "no OpenBLAS" in line:
            pytest.skip("numpy is not linked against OpenBLAS here")
        assert line == f"BLAS threads {expected}", (chosen, line)


def test_a_mesh_file_is_framed_lit_and_rendered(tmp_path):
    """`view MESH`: the camera looks at the mesh's bounding box centre and the whole mesh is in the frame."""
    mesh = Path(__file__).resolve().parents[2] / "scenes" / "meshes" / "torus_knot.ply"
    with connect(client_for(mesh)) as ws:
        hello = json.loads(ws.receive_text())
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "full"}))
        _header, parts = receive_frame(ws)
    assert hello["analytic"] is False and hello["scene"]["objects"][0]["shape"] == "mesh"
    image = decode_png(parts["a"], tmp_path)
    covered = np.abs(image - image[0, 0]).max(axis=2) > 0  # against the background (a mesh file's is grey)
    assert covered.any() and not (covered[0].any() or covered[-1].any() or covered[:, 0].any() or covered[:, -1].any())


def test_the_colour_setting_is_a_control_and_a_frame_is_encoded_as_it_says(scene_path, tmp_path):
    """render.colour (display or linear): the page has a control offering exactly the schema's values, the scene
    it opens says which, and a linear frame is the PNG `render` writes for it (through the sRGB curve), not the
    display one; a glTF opens in linear colour, as `render model.glb` does."""
    from raycast_phong.io.encoding import COLOURS
    page = Path(__file__).resolve().parents[2] / "raycast_phong" / "tools" / "view" / "static" / "index.html"
    control = re.search(r'<select data-key="render\.colour".*?</select>', page.read_text(), re.S)
    assert control and tuple(re.findall(r'value="(\w+)"', control[0])) == COLOURS
    with connect(client_for(scene_path)) as ws:
        assert json.loads(ws.receive_text())["scene"]["render"]["colour"] == "display"
        ws.send_text(json.dumps({"type": "render", "id": 1, "settings": {"render.colour": "linear"}}))
        _, linear = receive_frame(ws)
        ws.send_text(json.dumps({"type": "render", "id": 2, "settings": {}}))
        _, display = receive_frame(ws)
    shown = decode_png(linear["a"], tmp_path)
    np.testing.assert_array_equal(shown, rendered_png(rp.load_scene(scene_path, ["render.colour=linear"])))
    assert (shown.astype(int) - decode_png(display["a"], tmp_path)).max() > 10  # the curve lifts the mid-tones
    glb = Path(__file__).resolve().parents[2] / "scenes" / "meshes" / "still_life.glb"
    with connect(client_for(glb)) as ws:
        assert json.loads(ws.receive_text())["scene"]["render"]["colour"] == "linear"


def test_view_command_on_a_busy_port_fails_in_one_line(monkeypatch):
    import socket
    monkeypatch.delenv("RAYCAST_PHONG_DEBUG", raising=False)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        result = CliRunner().invoke(cli_app, ["view", "--port", str(port), "--no-browser"])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and f"cannot listen on 127.0.0.1:{port}" in result.output


@pytest.mark.parametrize("kind", ["fifo", "nan"])
def test_a_mesh_path_is_read_by_the_renderers_own_loader(tmp_path, kind):
    """`view MESH` reads the mesh as render does: a FIFO is refused at once (never blocks), a NaN vertex
    is refused naming the key, each in one line with exit 2."""
    import os
    path = tmp_path / "model.obj"
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    command = [sys.executable, "-m", "raycast_phong.cli", "view", str(path), "--no-browser", "--port", "0"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    [line] = done.stderr.strip().splitlines()
    # A mesh file is the scene, so the line names the file itself (no objects.0.path of a scene file).
    assert line.startswith(f"error: {path}: ") and ("named pipe" in line if kind == "fifo" else "NaN" in line), line


# ---------------------------------------------------------------- a page's frames reuse and cancel


@pytest.fixture
def counted(monkeypatch):
    """Counts of the expensive steps a frame may take: mesh files read, groups placed (world vertices and
    normals) and BVHs built (Embree scenes committed)."""
    from raycast_phong.geometry import build
    from raycast_phong.io.meshes import read as mesh_file
    from raycast_phong.renderer import embree_library as embree
    counts = {"reads": 0, "placed": 0, "bvhs": 0}

    def counting(name, function):
        def wrapper(*args, **kwargs):
            counts[name] += 1
            return function(*args, **kwargs)
        return wrapper
    monkeypatch.setattr(mesh_file, "read_file", counting("reads", mesh_file.read_file))
    monkeypatch.setattr(build, "place_group", counting("placed", build.place_group))
    monkeypatch.setattr(embree, "EmbreeScene", counting("bvhs", embree.EmbreeScene))
    return counts


def frame_of_settings(ws, request_id: int, settings: dict, quality: str = "draft") -> tuple[dict, dict]:
    ws.send_text(json.dumps({"type": "render", "id": request_id, "quality": quality, "settings": settings}))
    header, parts = receive_frame(ws)
    assert header["id"] == request_id
    return header, parts


def test_a_light_move_rebuilds_nothing_and_only_a_change_of_what_geometry_reads_rebuilds_it(tmp_path, counted):
    """A page's second frame with only a light moved (or the camera, a material, the shading) reads no mesh
    file, places no object and builds no BVH; moving the object places it and builds a BVH without reading the
    file again; a rewritten file is read again. Every frame is the PNG render() gives for its settings."""
    import shutil
    mesh = tmp_path / "knot.ply"
    shutil.copy(Path(__file__).resolve().parents[2] / "scenes" / "meshes" / "torus_knot.ply", mesh)
    client = client_for(mesh)
    client.app.state.warming.result(120)  # the server's own warm-up frame reads and builds too: not counted
    size = {"render.width": 48, "render.height": 36}
    light = {**size, "lights.0.position": [3.0, 4.0, 5.0]}
    unchanged = [light, {**light, "camera.position": [0.5, 1.0, 6.0]}, {**light, "render.shading": "flat"},
                 {**light, "render.shading": "gouraud"}, {**light, "materials.default.kd": [0.2, 0.4, 0.6]}]
    moved = {**light, "objects.0.translate": [0.25, 0.0, 0.0]}
    shown = []
    with connect(client) as ws:
        ws.receive_text()
        before = dict(counted)
        shown.append(frame_of_settings(ws, 1, size)[1]["a"])
        first = dict(counted)
        assert first["placed"] == before["placed"] + 1 and first["bvhs"] == before["bvhs"] + 1  # the page's own
        for request_id, settings in enumerate(unchanged, start=2):
            shown.append(frame_of_settings(ws, request_id, settings)[1]["a"])
            assert counted == first, settings
        shown.append(frame_of_settings(ws, 10, moved)[1]["a"])
        assert counted == {**first, "placed": first["placed"] + 1, "bvhs": first["bvhs"] + 1}
        data = mesh.read_bytes()
        mesh.unlink()
        mesh.write_bytes(data)  # the same bytes in a new file: read again, as render would
        os.utime(mesh, ns=(10**9, 10**9))  # another mtime whatever the file system's clock and inode reuse
        frame_of_settings(ws, 11, moved)
        assert counted["reads"] == first["reads"] + 1
    source = open_scene(mesh)
    for png, settings in zip(shown, [size, *unchanged, moved]):
        np.testing.assert_array_equal(decode_png(png, tmp_path), rendered_png(draft_of(scene_with(source, settings))))


def held_until_cancelled(monkeypatch, held) -> tuple:
    """A render hook for client_for that notes each frame's cancelled(), and the bands of the tiles `held(tile)`
    picks wait (at most 20 s for the frame) until it answers True: (the hook, the rows of the bands held)."""
    from raycast_phong.renderer import prepare
    asked, calls = {}, []

    def render(session, scene, **options):
        asked["cancelled"] = options.get("cancelled")
        return session_render(session, scene, **options)

    band = prepare.TileWork.__call__

    def held_band(tile, rows):
        if held(tile):
            calls.append(rows)
            deadline = asked.setdefault("deadline", time.monotonic() + 20)  # one wait for the frame, not per band
            while not (asked.get("cancelled") and asked["cancelled"]()) and time.monotonic() < deadline:
                time.sleep(0.01)
        return band(tile, rows)
    monkeypatch.setattr(prepare.TileWork, "__call__", held_band)
    return render, calls


def test_a_newer_request_cancels_a_running_full_frame_between_bands(scene_path, monkeypatch):
    """A full frame of 8 × 8 samples (40 bands of 3 rows) is refined: a preview of one sample a pixel first, then
    the full frame. A draft sent while the full frame's first bands run stops it: the bands already started end,
    no other starts, the page is told how many were done, and the draft follows."""
    from raycast_phong.io import system
    # The full frame's bands wait until the newer request has cancelled it.
    render, calls = held_until_cancelled(monkeypatch, lambda tile: tile.rays.samples > 1)
    settings = {"render.width": 160, "render.height": 120, "render.samples": 8}
    with connect(client_for(scene_path, render=render)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "full", "settings": settings}))
        preview, _ = receive_frame(ws)
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "draft", "settings": settings}))
        message = ws.receive()
        while message.get("text") is not None and json.loads(message["text"])["type"] == "progress":
            message = ws.receive()
        told = json.loads(message["text"]) if message.get("text") is not None else unpack(message["bytes"])[0]
        draft, _ = receive_frame(ws)
    assert (preview["id"], preview["quality"], preview["stats"]["a"]["rays"]) == (1, "preview", 160 * 120)
    assert told["type"] == "cancelled" and told["id"] == 1 and told["of"] == 40, told
    # Only the bands the render threads had started when it was cancelled were rendered (one a thread).
    assert told["done"] == len(calls) <= system.default_threads() < 40
    assert (draft["id"], draft["quality"]) == (2, "draft")


def test_a_full_request_stops_a_running_draft_between_bands(scene_path, monkeypatch):
    """A release's full request while the drag's last draft renders: the draft stops at its next band (the page is
    told it was cancelled, with the bands done) and the full frame follows, instead of waiting for a draft of a
    stale state that the page would paint first."""
    # The draft's bands (of 320 × 180) wait until the full request has cancelled it.
    render, calls = held_until_cancelled(monkeypatch, lambda tile: tile.film.rgb.shape[1] == 320)
    from raycast_phong.io import system
    monkeypatch.setattr(system, "default_threads", lambda: 1)  # one band thread: the second band is not started
    settings = {"render.width": 640, "render.height": 360}
    with connect(client_for(scene_path, render=render)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "draft", "settings": settings}))
        deadline = time.monotonic() + 20
        while not calls and time.monotonic() < deadline:
            time.sleep(0.01)
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "full", "settings": settings}))
        told = json.loads(ws.receive_text())
        while told["type"] == "progress":
            told = json.loads(ws.receive_text())
        full, _ = receive_frame(ws)
    assert told["type"] == "cancelled" and told["id"] == 1 and told["done"] < told["of"] == 2, told
    assert (full["id"], full["quality"]) == (2, "full")


def test_a_full_frame_of_several_samples_is_refined_from_a_preview(scene_path, tmp_path):
    """At rest a frame of 3 × 3 samples comes twice: a preview of one sample a pixel, then the full frame; each is
    the PNG render() gives, and the exact errors follow the full frame only."""
    settings = {"render.samples": 3}
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 4, "quality": "full", "settings": settings,
                                 "reference": True}))
        preview, first = receive_frame(ws)
        full, last = receive_frame(ws)
        errors = json.loads(ws.receive_text())
    assert (preview["quality"], full["quality"], errors["type"], errors["id"]) == ("preview", "full", "errors", 4)
    one = rp.load_scene(scene_path)
    np.testing.assert_array_equal(decode_png(first["a"], tmp_path), rendered_png(one))
    three = rp.load_scene(scene_path, ["render.samples=3"])
    np.testing.assert_array_equal(decode_png(last["a"], tmp_path), rendered_png(three))


def test_a_full_request_sent_while_a_preview_renders_skips_the_older_full_frame(scene_path, monkeypatch):
    """Request 1 (3 × 3 samples) renders its preview; request 2, full, comes meanwhile and waits as the committed
    frame. The preview is shown (a committed request's first frame always is), but 1's full frame is stale and
    never rendered: 2's preview and full frame follow. Catches `waiting` that sees a waiting draft only."""
    from raycast_phong.renderer import prepare
    running, go = threading.Event(), threading.Event()
    band = prepare.TileWork.__call__

    def held_band(tile, rows):
        if tile.film.rgb.shape[1] == 96 and tile.rays.samples == 1 and not go.is_set():  # request 1's preview
            running.set()
            go.wait(30)
        return band(tile, rows)
    monkeypatch.setattr(prepare.TileWork, "__call__", held_band)
    settings = {"render.samples": 3, "render.width": 96, "render.height": 72}  # no warm-up renders this size
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "full", "settings": settings}))
        assert running.wait(60)  # waits there until 2 is queued
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "full", "settings": settings}))
        time.sleep(0.2)  # request 2 is queued before the preview goes on
        go.set()
        frames = []
        while not frames or (frames[-1]["id"], frames[-1]["quality"]) != (2, "full"):
            frames.append(receive_frame(ws)[0])
    assert [(header["id"], header["quality"]) for header in frames] == [(1, "preview"), (2, "preview"),
                                                                         (2, "full")]


def test_each_page_has_one_frame_cache_released_when_it_closes(scene_path, monkeypatch):
    """A page's frames share one FrameCache (its geometry and BVH), and nothing holds it once the page closes."""
    import gc
    import weakref

    from raycast_phong.tools.view import session
    made = []

    from raycast_phong.renderer.reuse import FrameCache

    class Counted(FrameCache):
        def __init__(self):
            super().__init__()
            made.append(weakref.ref(self))
    monkeypatch.setattr(session, "frame_cache", Counted)
    client = client_for(scene_path)
    with connect(client) as one, connect(client) as two:
        for ws in (one, two):
            ws.receive_text()
            for request_id in (1, 2):
                frame_of_settings(ws, request_id, {"lights.0.position": [1.0, request_id, 3.0]})
        assert len(made) == 2 and all(ref() is not None for ref in made)
    deadline = time.monotonic() + 30
    while any(ref() is not None for ref in made) and time.monotonic() < deadline:
        gc.collect()
        time.sleep(0.05)
    assert all(ref() is None for ref in made)


def test_capture_asks_for_two_saves_at_once_and_gets_both(scene_path):
    """The page's capture sends a PNG save and a TOML save back to back: both are answered."""
    client = client_for(scene_path)
    with connect(client) as ws:
        ws.receive_text()
        for request_id, what in ((1, "png"), (2, "toml")):
            ws.send_text(json.dumps({"type": "save", "id": request_id, "what": what, "settings": {}}))
        ws.send_text(json.dumps({"type": "render", "id": 3, "quality": "draft"}))  # answered after the saves
        got = [unpack(ws.receive_bytes())[0] for _ in range(2)]
        assert [(h["type"], h["what"]) for h in got] == [("saved", "png"), ("saved", "toml")]
        assert receive_frame(ws)[0]["id"] == 3


def test_every_page_renders_on_the_servers_few_threads(scene_path):
    """Work is bounded per server: four pages' frames run on the server's FRAME_THREADS render threads, not on a
    thread per page (twelve pages used to make 42 threads)."""
    from raycast_phong.tools.view import session
    threads = set()

    def noted(session, scene, **options):
        threads.add((threading.get_ident(), threading.current_thread().name))
        return session_render(session, scene, **options)

    client = client_for(scene_path, render=noted)
    with connect(client) as a, connect(client) as b, connect(client) as c, connect(client) as d:
        pages = (a, b, c, d)
        for ws in pages:
            ws.receive_text()
            ws.send_text(json.dumps({"type": "render", "id": 1, "quality": "draft"}))
        for ws in pages:
            receive_frame(ws)
    assert 1 <= len(threads) <= session.FRAME_THREADS == 2  # the pages stay open: no thread id is reused
    assert all(name.startswith("view-render") for _, name in threads)


def test_the_bands_of_every_frame_run_on_the_servers_band_threads_which_stop_with_it(scene_path, monkeypatch):
    """A frame's bands run on threads the server keeps for all its frames (a pool started for each frame waited 1-2 ms
    for its threads), at most the renderer's default number, shared by its pages; they end with the server.
    Frames stay the PNGs render() gives."""
    from websockets.sync.client import connect as socket_to

    from raycast_phong.io import system
    from raycast_phong.renderer import prepare
    from raycast_phong.tools.view import running
    seen = []
    band = prepare.TileWork.__call__

    def noted(tile, rows):
        if tile.film.rgb.shape[1] == 320:  # the pages' drafts (not the server's own warm-up frame)
            seen.append(threading.current_thread())
        return band(tile, rows)
    monkeypatch.setattr(prepare.TileWork, "__call__", noted)
    settings = {"render.width": 640, "render.height": 360}  # drafts of 320×180: two bands each
    with running(scene_path) as url:
        origin = url.split("/?", 1)[0]
        address = origin.replace("http://", "ws://") + "/socket?token=" + url.split("token=", 1)[1]
        with socket_to(address, origin=origin, max_size=None) as one, socket_to(address, origin=origin,
                                                                                max_size=None) as two:
            for ws in (one, two):
                json.loads(ws.recv())
            for request_id in range(1, 4):
                for ws in (one, two):
                    ws.send(json.dumps({"type": "render", "id": request_id, "quality": "draft",
                                        "settings": {**settings, "lights.0.position": [request_id, 2, 3]}}))
                    message = ws.recv()
                    while not isinstance(message, bytes):
                        message = ws.recv()
                    png = unpack(message)[1]["a"]
        threads = set(seen)
    assert len(seen) >= 6 * 2 and all(thread.name.startswith("view-bands") for thread in threads), threads
    assert len({thread.ident for thread in threads}) <= system.default_threads()
    for thread in threads:
        thread.join(10)
    assert not any(thread.is_alive() for thread in threads)
    scene = draft_of(scene_with(open_scene(scene_path), {**settings, "lights.0.position": [3, 2, 3]}))
    np.testing.assert_array_equal(decode_png(png, scene_path.parent), rendered_png(scene))


def test_the_page_is_served_before_the_renderer_is_loaded(scene_path, monkeypatch):
    """Start-up: making the app imports neither numba nor OpenImageIO (the first frame does), and the kernels'
    warm-up waits for the first page (or WARM_AFTER seconds), so the HTML is not queued behind them."""
    made = subprocess.run([sys.executable, "-c", f"""
import sys
from raycast_phong.tools.view import create_app, open_scene
create_app(open_scene({str(scene_path)!r}), "t" * 40, ["http://testserver"])
print(sorted(name for name in ("numba", "OpenImageIO", "raycast_phong.renderer.frame") if name in sys.modules))
"""], capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[2])})
    assert made.returncode == 0 and made.stdout.strip() == "[]", made.stdout + made.stderr
    from raycast_phong.tools.view import server, session
    started = threading.Event()
    monkeypatch.setattr(session, "WARM_AFTER", 60)
    # Only this app's warm-up counts: an earlier test's app in this worker still has its WARM_AFTER timer, which
    # would call the patched warm (that set the event at once in a full fresh-clone run).
    monkeypatch.setattr(server, "warm", lambda source: source.folder == scene_path.parent and started.set())
    client = client_for(scene_path)
    assert not started.wait(0.5)  # nothing asked for a page yet
    assert client.get(f"/?token={TOKEN}").status_code == 200
    assert started.wait(30)
    client.app.state.warming.result(30)


def test_a_scene_the_page_opens_is_measured_in_utf8_bytes_not_characters():
    """The 60,000 the page allows are bytes, what the socket carries: 40,000 "é" are 80,000 bytes (refused,
    said in bytes) though 40,000 characters; 29,999 "é" and 2 ASCII bytes (60,000 bytes) reach the TOML parser."""
    from raycast_phong.tools.view import session
    from raycast_phong.tools.view.server import loaded
    assert session.MAX_SCENE_BYTES == 60_000
    refused = loaded(None, {"type": "load", "id": 3, "name": "accents.toml", "text": "é" * 40_000})
    assert refused == {"type": "error", "id": 3, "message": "accents.toml: 80,000 bytes; a scene file the page "
                                                            "opens is at most 60,000 bytes"}, refused
    parsed = loaded(None, {"type": "load", "id": 4, "name": "fits.toml", "text": "é" * 29_999 + "=1"})
    assert parsed["type"] == "error" and "not a TOML scene" in parsed["message"], parsed


def test_a_deleted_scene_file_is_said_once_and_its_return_reloads(scene_path, monkeypatch):
    """The watched file removed (not an editor's quick replace, which GONE_AFTER waits past): every page is told once
    in one line, the last scene kept; put back, it is read again. A replace faster than GONE_AFTER says nothing."""
    from raycast_phong.tools.view import session
    monkeypatch.setattr(session, "WATCH_EVERY", 0.05)
    monkeypatch.setattr(session, "GONE_AFTER", 0.3)
    text = scene_path.read_text()
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        scene_path.unlink()
        gone = json.loads(ws.receive_text())
        assert gone["type"] == "error" and gone["file"] is True, gone
        assert gone["message"] == (f"{scene_path.name}: the scene file is gone (deleted or moved); the page keeps the "
                                   "scene as it was until the file is back")
        time.sleep(0.5)  # still gone: not said again
        scene_path.write_text(text.replace("ambient = [0.1, 0.1, 0.1]", "ambient = [0.5, 0.2, 0.1]"))
        back = json.loads(ws.receive_text())
        assert back["type"] == "hello" and back["reloaded"] and back["problem"] is None, back
        assert back["scene"]["ambient"] == [0.5, 0.2, 0.1]


def test_a_page_message_is_measured_in_utf8_bytes_not_characters():
    """The socket carries bytes: 300,000 "é" are 600,038 bytes of message, over MAX_MESSAGE_BYTES though fewer
    characters; refused in one line in bytes, as an ASCII message of that size is."""
    from raycast_phong.errors import ViewError
    from raycast_phong.tools.view import session
    text = '{"type": "render", "id": 9, "pad": "' + "é" * 300_000 + '"}'
    assert len(text) < session.MAX_MESSAGE_BYTES < len(text.encode())
    with pytest.raises(ViewError, match=r"^message of 600,038 bytes; allowed: at most 524,288$"):
        session.parse(text)
    assert session.parse('{"type": "render", "id": 9, "pad": "' + "é" * 200_000 + '"}')["id"] == 9


# ---------------------------------------------------------------- the view's limits at their value and one past

def test_a_page_message_of_exactly_the_limit_is_parsed_and_one_byte_more_refused():
    """MAX_MESSAGE_BYTES is the most a message may be: one of exactly 524,288 bytes is read, one byte more is one
    line (the tests above are far past it). Catches `>` made `>=`, and the limit moved by a byte."""
    from raycast_phong.errors import ViewError
    from raycast_phong.tools.view import session
    head, tail = '{"type": "render", "id": 9, "pad": "', '"}'
    exact = head + "x" * (session.MAX_MESSAGE_BYTES - len(head) - len(tail)) + tail
    assert len(exact.encode()) == 524_288 and session.parse(exact)["id"] == 9
    with pytest.raises(ViewError, match=r"^message of 524,289 bytes; allowed: at most 524,288$"):
        session.parse(exact.replace('"x', '"xx', 1))


def test_a_scene_the_page_opens_of_one_byte_past_60000_is_refused():
    """60,000 bytes reach the TOML parser (test above); 60,001 are the size's one line. Catches the limit moved by
    one byte, which the far larger texts above let through."""
    from raycast_phong.tools.view.server import loaded
    refused = loaded(None, {"type": "load", "id": 5, "name": "a.toml", "text": "#" * 60_001})
    assert refused == {"type": "error", "id": 5, "message": "a.toml: 60,001 bytes; a scene file the page opens is "
                                                            "at most 60,000 bytes"}, refused


def test_the_view_takes_256_settings_and_refuses_257(scene_path):
    """MAX_SETTINGS keys per request: 256 apply, 257 are one line naming the count. Catches `>` made `>=` and the
    limit moved by one (no test sent that many keys)."""
    from raycast_phong.tools.view.server import MAX_SETTINGS, ViewError
    source = open_scene(scene_path)
    settings = {f"materials.m{i}.kd": 0.5 for i in range(MAX_SETTINGS)}
    assert MAX_SETTINGS == 256 and len(scene_with(source, settings).materials) == 257  # red and 256 more
    with pytest.raises(ViewError, match=r"^settings: 257 keys; allowed: at most 256$"):
        scene_with(source, {**settings, "materials.extra.kd": 0.5})


def test_the_view_s_ray_limit_holds_at_its_value(scene_path, monkeypatch):
    """MAX_VIEW_RAYS (1920 × 1080 × 4²) is allowed and the nearest frame past it (2404 × 13801 × 1², 1920·1080·16 + 1
    being prime) refused; with the limit set to the tiny scene's 64 × 48 rays, that frame passes and one ray fewer
    refuses it. Catches `>` made `>=` and the limit moved by a ray."""
    from raycast_phong.tools.view import server
    source = open_scene(scene_path)
    full = {"render.width": 1920, "render.height": 1080, "render.samples": 4}
    assert scene_with(source, full).render.samples == 4
    with pytest.raises(server.ViewError, match=r"render\.samples: 2404×13801 pixels × 1² samples is more than"):
        scene_with(source, {"render.width": 2404, "render.height": 13801})
    monkeypatch.setattr(server, "MAX_VIEW_RAYS", 64 * 48)
    assert scene_with(source, {}).render.width == 64
    monkeypatch.setattr(server, "MAX_VIEW_RAYS", 64 * 48 - 1)
    with pytest.raises(server.ViewError, match=r"64×48 pixels × 1² samples is more than the view's 3,071 rays"):
        scene_with(source, {})


def test_a_frame_over_its_share_of_the_servers_memory_budget_is_refused_on_the_page(scene_path):
    """`view --max-memory B`: each frame may use B // FRAME_THREADS (the frames that render at once, over all the
    pages, share the server's budget). A full frame whose estimate is exactly its share renders; with a budget two
    bytes smaller (a share one byte short) the page is told the memory line, and the next page's frame of a
    smaller scene still renders. Before, a page's frame had the whole default budget, so frames at once could
    ask for twice the memory there is."""
    from raycast_phong.io.system import format_bytes
    from raycast_phong.tools.view.server import frame_of
    from raycast_phong.tools.view.session import FRAME_THREADS
    need = rp.Renderer().check_fits(frame_of(scene_with(open_scene(scene_path), {}))).total
    with connect(client_for(scene_path, max_memory=FRAME_THREADS * need)) as ws:
        ws.receive_text()
        header, parts = frame_of_settings(ws, 1, {}, quality="full")
        assert header["quality"] == "full" and parts["a"][:8] == b"\x89PNG\r\n\x1a\n"
    with connect(client_for(scene_path, max_memory=FRAME_THREADS * need - FRAME_THREADS + 1)) as ws:
        ws.receive_text()
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "full", "settings": {}}))
        answer = json.loads(ws.receive_text())
        while answer["type"] == "progress":
            answer = json.loads(ws.receive_text())
        assert answer["type"] == "error" and answer["id"] == 2, answer
        assert f"above the {format_bytes(need - 1)} budget" in answer["message"], answer
        assert "\n" not in answer["message"]
        smaller = {"render.width": 32, "render.height": 24}
        assert frame_of_settings(ws, 3, smaller, quality="full")[0]["quality"] == "full"


def test_a_pages_work_is_queued_at_what_each_step_costs(scene_path, monkeypatch):
    """The frame threads order work by its cost (tools/view/frame_queue.py): a draft is queued at a draft's cost,
    a full request's steps (validation) at a check's, after a draft's, and its preview and full frame at theirs, a
    save at a full frame's. Recorded from the queue's one entry point."""
    from raycast_phong.tools.view import frame_queue
    queued = []
    submit_at = frame_queue.FrameQueue.submit_at

    def recorded(self, cost, fn, *args, **kwargs):
        queued.append((getattr(fn, "__name__", "?"), args[-1] if fn.__name__ == "frame" else None, cost))
        return submit_at(self, cost, fn, *args, **kwargs)
    monkeypatch.setattr(frame_queue.FrameQueue, "submit_at", recorded)
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        frame_of_settings(ws, 1, {}, quality="draft")
        ws.send_text(json.dumps({"type": "render", "id": 2, "quality": "full", "settings": {"render.samples": 2}}))
        assert receive_frame(ws)[0]["quality"] == "preview" and receive_frame(ws)[0]["quality"] == "full"
        ws.send_text(json.dumps({"type": "save", "id": 3, "what": "toml", "settings": {}}))
        ws.receive_bytes()
    cost = frame_queue.COST
    assert cost["draft"] < cost["check"] < cost["preview"] < cost["full"]
    assert queued == [("frame", "draft", cost["draft"]), ("steps", None, cost["check"]),
                      ("frame", "preview", cost["preview"]), ("frame", "full", cost["full"]),
                      ("save", None, cost["full"])], queued


@pytest.mark.parametrize(("size", "draft"), [((640, 360), (320, 180)), ((639, 359), (320, 180)),
                                             ((641, 361), (319, 180)), ((64, 48), (32, 24)),
                                             ((1280, 720), (320, 180)), ((1920, 1080), (320, 180)),
                                             ((16384, 1), (8192, 1)), ((16384, 64), (3840, 15))])
def test_a_draft_is_half_each_side_and_at_most_a_640_by_360_frames_pixels(scene_path, size, draft):
    """A frame up to 640×360 drafts at half each side (an odd side rounds up); a larger one at the same share of
    each side, down to DRAFT_PIXELS (320×180): a 1280×720 frame's drafts cost what a 640×360 frame's do."""
    from raycast_phong.tools.view.server import DRAFT_PIXELS
    scene = scene_with(open_scene(scene_path), {"render.width": size[0], "render.height": size[1],
                                                "render.samples": 4})
    shaped = draft_of(scene).render
    assert (shaped.width, shaped.height, shaped.samples) == (*draft, 1)
    assert shaped.width * shaped.height <= max(DRAFT_PIXELS, ((size[0] + 1) // 2) * ((size[1] + 1) // 2))


def test_the_scene_file_watched_is_any_file_load_reads_as_a_scene(scene_path, tmp_path):
    """The view watches what scene.load reads as a scene file (is_mesh_file's rule: any suffix no mesh format
    claims, none at all included), so a scene saved without a suffix reloads too; a mesh file is not watched (a
    render reads it anew)."""
    bare = tmp_path / "lecture"
    bare.write_text(scene_path.read_text())
    assert open_scene(bare).watched == bare and open_scene(scene_path).watched == scene_path
    mesh = tmp_path / "tetra.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    assert open_scene(mesh).watched is None


@pytest.mark.parametrize(("objects", "spheres"), [(64, 64), (65, 1)])
def test_a_frame_names_up_to_max_spheres_bounding_spheres_and_one_round_more(objects, spheres):
    """The page's near limit: MAX_SPHERES (64) objects each get their sphere, 65 get one sphere round them all.
    Catches `>` made `>=` (64 objects merged into one) and a limit one off."""
    from raycast_phong.geometry.build import build_geometry
    from raycast_phong.renderer.reuse import FrameCache
    from raycast_phong.tools.view.server import MAX_SPHERES, object_spheres
    assert MAX_SPHERES == 64
    scene = rp.validate_scene({"objects": [{"shape": "box", "translate": [3 * i, 0, 0]} for i in range(objects)]})
    cache = FrameCache()
    cache.derived(build_geometry(scene))
    found = object_spheres(cache, objects)
    assert len(found) == spheres
    if spheres > 1:
        assert [round(sphere[0]) for sphere in found] == [3 * i for i in range(objects)]


def test_each_malformed_page_message_gets_its_own_line_and_the_socket_stays(scene_path):
    """What the page's protocol refuses, each in its own words (what the message must be and what is allowed),
    answered under the message's id, never an internal error; the same socket then renders."""
    cases = [
        ([1, 2], "message must be a table with type 'render', 'save' or 'load'"),
        ({"type": "delete", "id": 1}, "message must be a table with type 'render', 'save' or 'load'"),
        ({"type": "render", "id": 2, "settings": [1, 2]}, "settings must be a table of KEY.PATH: value"),
        ({"type": "save", "id": 3, "what": "gif", "settings": {}}, "save: 'gif'; allowed: 'toml', 'png' or 'exr'"),
        ({"type": "load", "id": 4, "name": "a.toml", "text": 3}, "load: text and name must be strings"),
        ({"type": "load", "id": 5, "name": ["a"], "text": ""}, "load: text and name must be strings"),
        ({"type": "load", "id": 6, "name": "a.json", "text": "[1, 2]"}, "a.json: a scene file is a table of tables"),
    ]
    with connect(client_for(scene_path)) as ws:
        ws.receive_text()
        for message, says in cases:
            ws.send_text(json.dumps(message))
            answer = json.loads(ws.receive_text())
            assert answer["type"] == "error" and answer["message"] == says, (message, answer)
            assert answer.get("id") == (message.get("id") if isinstance(message, dict) else None)
        ws.send_text(json.dumps({"type": "render", "id": 9, "settings": {"render.shading": "flat"}}))
        receive_frame(ws)


def test_a_loaded_file_the_pages_settings_cannot_make_is_refused_naming_the_key(tmp_path):
    """Loading a saved scene gives the page settings that make it from the view's scene, or one line why none
    can: a key the view's scene sets and the file leaves unset (a setting cannot unset it), or values the file
    may hold but the view refuses (16384² pixels: past the view's rays a frame)."""
    from raycast_phong.io.scene_toml import scene_toml
    from raycast_phong.tools.view.server import ViewError, settings_from
    path = write_tiny_scene(tmp_path, 32, 24)
    path.write_text(path.read_text().replace('shape = "icosphere"', 'shape = "icosphere"\nname = "ball"'))
    opened = open_scene(path)
    text = scene_toml(scene_with(opened, {}))
    assert 'name = "ball"' in text and settings_from(opened, text, "same.toml") == {}
    with pytest.raises(ViewError) as refused:
        settings_from(opened, text.replace('name = "ball"\n', ""), "nameless.toml")
    assert str(refused.value) == "nameless.toml: objects.0.name is unset there and set here; a page setting " \
                                 "cannot unset a key"
    huge = text.replace("width = 32", "width = 16384").replace("height = 24", "height = 16384")
    assert "width = 16384" in huge and "height = 16384" in huge
    with pytest.raises(ViewError) as refused:
        settings_from(opened, huge, "huge.toml")
    message = str(refused.value)
    assert message.startswith("huge.toml: these settings do not apply to this view's scene: ") and \
        "rays per frame" in message and "\n" not in message, message
