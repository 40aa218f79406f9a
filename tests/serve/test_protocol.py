"""Socket protocol: validation, error replies, fuzz (the server survives), security."""

from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.serve.protocol import MESSAGE_TYPES, ProtocolError, parse_message
from warerover_phys.serve.server import resolve_under


@pytest.mark.parametrize("text, why", [
    ("nope", "not JSON"),
    ("[1, 2]", "JSON object"),
    ('{"type": "launch"}', "unknown message type"),
    ('{"type": "fail"}', "agv: Field required"),
    ('{"type": "fail", "agv": "x"}', "agv"),
    ('{"type": "step", "count": 0}', "count"),
    ('{"type": "pause", "extra": 1}', "extra"),
    ('{"type": "speed", "ticks_per_s": -1}', "ticks_per_s"),
    ('{"type": "restart", "executor": "warp"}', "executor"),
])
def test_bad_messages_say_why(text, why):
    with pytest.raises(ProtocolError, match=why):
        parse_message(text)


def test_every_type_has_a_valid_example():
    examples = {"step": {"count": 2}, "speed": {"ticks_per_s": 5}, "fail": {"agv": 1},
                "repair": {"agv": 1}, "inspect": {"agv": 0}, "layout_load": {"path": "a.yaml"},
                "layout_check": {"layout": {"rows": 1, "cols": 1, "cells": "."}},
                "layout_save": {"path": "a.yaml",
                                "layout": {"rows": 1, "cols": 1, "cells": "."}},
                "replay_open": {"path": "x.npz"}, "export_glb": {"path": "a.glb"}}
    for kind in MESSAGE_TYPES:
        msg = parse_message(json.dumps({"type": kind, **examples.get(kind, {})}))
        assert msg.type == kind


def test_resolve_under_refuses_escapes(tmp_path):
    (tmp_path / "ok.yaml").write_text("a: 1")
    assert resolve_under(tmp_path, "ok.yaml", must_exist=True) == tmp_path / "ok.yaml"
    for bad in ("../x.yaml", "/etc/passwd", "a/../../x.yaml", "..", "x\0.yaml"):
        with pytest.raises(ProtocolError):
            resolve_under(tmp_path, bad, suffixes=(".yaml",))
    (tmp_path / "link.yaml").symlink_to("/etc/hostname")
    with pytest.raises(ProtocolError, match="outside"):
        resolve_under(tmp_path, "link.yaml")
    with pytest.raises(ProtocolError, match="must end in"):
        resolve_under(tmp_path, "ok.txt", suffixes=(".yaml",))


def test_socket_errors_and_controls(serve, client_for, tmp_path):
    srv = serve()
    c = client_for(srv)
    assert c.hello["protocol"] == 1 and c.hello["scene"]["agvs"]
    for bad in ("{", '{"type": "fail", "agv": 10000}', '{"type": "repair", "agv": 0}',
                '{"type": "layout_load", "path": "../../etc/passwd.yaml"}',
                '{"type": "replay_open", "path": "missing.npz"}', b"\x00\x01"):
        reply = c.request(bad, "error")
        assert reply["type"] == "error" and reply["error"]
    r = c.request({"type": "pause", "id": 7})
    assert r == {"type": "ack", "of": "pause", "paused": True, "ticks_per_s": 20.0, "id": 7}
    tick = c.request({"type": "step", "count": 3})["tick"]
    assert c.request({"type": "ping"}, "pong")["tick"] == tick
    r = c.request({"type": "add_orders", "count": 2})
    assert len(r["orders"]) == 2
    r = c.request({"type": "export_glb", "path": "out/layout.glb"}, "exported", "error")
    assert r["type"] == "exported" and (tmp_path / "out" / "layout.glb").stat().st_size > 1000


json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False)
                           | st.text(max_size=20), lambda ch: st.lists(ch, max_size=4)
                           | st.dictionaries(st.text(max_size=8), ch, max_size=4), max_leaves=12)


@settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_fuzzed_messages_get_error_replies_and_the_server_survives(data, serve_once):
    srv, c = serve_once
    kind = data.draw(st.sampled_from([*MESSAGE_TYPES, "bogus", None]))
    body = data.draw(st.dictionaries(st.sampled_from(
        ["agv", "count", "path", "layout", "ticks_per_s", "executor", "seed", "id", "map",
         "what", "suffixes", "station", "sku", "repair_ticks", "x"]), json_values, max_size=4))
    if kind is not None:
        body["type"] = kind
    body.pop("id", None)
    c.send(json.dumps(body))
    reply = c.recv_type("error", "ack", "pong", "agv", "files", "layout", "check", "saved",
                        "exported", "replay")
    assert reply["type"]
    assert c.request({"type": "ping"}, "pong")["type"] == "pong"


@pytest.fixture(scope="module")
def serve_once(tmp_path_factory):
    from .conftest import SERVE_EXTRA

    for mod in ("starlette", "uvicorn", "websockets"):
        pytest.importorskip(mod, reason=SERVE_EXTRA)
    from warerover_phys.serve.server import ServerThread, create_app

    from .conftest import Client

    root = tmp_path_factory.mktemp("fuzz")
    srv = ServerThread(create_app(root=root, paused=True)).start()
    c = Client(srv.url)
    yield srv, c
    c.close()
    srv.stop()


def test_origin_and_host_checks(serve):
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    srv = serve()
    ws_url = srv.url.replace("http", "ws") + "/ws"
    with pytest.raises(InvalidStatus):
        with connect(ws_url, origin="http://evil.example"):
            pass
    with connect(ws_url, origin=srv.url) as ok:
        assert json.loads(ok.recv(timeout=10))["type"] == "hello"
    import urllib.error
    import urllib.request

    req = urllib.request.Request(srv.url + "/", headers={"Host": "evil.example"})
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(req, timeout=10)
    assert err.value.code == 400
    assert urllib.request.urlopen(srv.url + "/", timeout=10).status == 200
