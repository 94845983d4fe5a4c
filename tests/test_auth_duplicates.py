"""Two ``Authorization`` headers (issue 36, item 9): which one counts would depend on the server (the
first) or a proxy (the last, or both joined), so a write carrying more than one is refused with 400
and one line, whatever their order and whether or not the service has a token; reads ignore them."""

from __future__ import annotations

import socket

import pytest

pytest.importorskip("fastapi")
from fastapi.testclient import TestClient  # noqa: E402

import synthetic_store as synth  # noqa: E402
from illumix.service.app import create_app  # noqa: E402
from illumix.service.models import ILLUMINANT_CSV_EXAMPLE  # noqa: E402
from illumix.store import CubeStore  # noqa: E402
from server_testutil import ThreadServer  # noqa: E402

TOKEN = "right-token"
RIGHT, WRONG = ("Authorization", f"Bearer {TOKEN}"), ("Authorization", "Bearer wrong-token")


@pytest.fixture(scope="module")
def store_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("auth") / "store"
    synth.build(path, h=8, w=8, extras=False)
    return path


@pytest.fixture(scope="module")
def client(store_path):
    with TestClient(create_app(CubeStore.open(str(store_path), mode="a"), token=TOKEN, cache_mb=16)) as c:
        yield c


def _upload(client, name: str, headers):
    return client.post("/illuminants", data={"name": name}, files={"file": ("l.csv", ILLUMINANT_CSV_EXAMPLE)},
                       headers=headers)


def _refused_as_duplicate(r) -> None:
    assert r.status_code == 400, r.text
    body = r.json()
    assert body["code"] == "duplicate_authorization" and "\n" not in body["detail"], body
    assert "2 Authorization headers" in body["detail"] and "exactly one" in body["detail"], body


@pytest.mark.parametrize("order", [(RIGHT, WRONG), (WRONG, RIGHT), (RIGHT, RIGHT)], ids=["right,wrong",
                                                                                         "wrong,right", "right,right"])
def test_two_authorization_headers_are_refused_in_any_order(client, order):
    _refused_as_duplicate(_upload(client, "dup-lamp", list(order)))
    _refused_as_duplicate(client.delete("/illuminants/dup-lamp", headers=list(order)))
    assert "dup-lamp" not in client.get("/illuminants").json()["uploaded"]


def test_one_header_still_decides(client):
    assert _upload(client, "one-lamp", [WRONG]).status_code == 401
    assert _upload(client, "one-lamp", [RIGHT]).status_code == 201
    assert client.delete("/illuminants/one-lamp", headers=[RIGHT]).status_code == 200


def test_reads_ignore_them_and_an_open_service_refuses_them_too(client, store_path):
    assert client.get("/illuminants", headers=[RIGHT, WRONG]).status_code == 200
    with TestClient(create_app(CubeStore.open(str(store_path), mode="a"), token=None, cache_mb=16)) as open_client:
        _refused_as_duplicate(_upload(open_client, "open-lamp", [WRONG, WRONG]))
        assert _upload(open_client, "open-lamp", [WRONG]).status_code == 201


def test_a_real_server_sees_both_headers(store_path):
    """Over uvicorn (h11), the two headers reach the app as two: the same 400."""
    body = ILLUMINANT_CSV_EXAMPLE.encode()
    form = (b"--b\r\nContent-Disposition: form-data; name=\"name\"\r\n\r\nsock-lamp\r\n--b\r\n"
            b"Content-Disposition: form-data; name=\"file\"; filename=\"l.csv\"\r\n\r\n" + body + b"\r\n--b--\r\n")
    app = create_app(CubeStore.open(str(store_path), mode="a"), token=TOKEN, cache_mb=16)
    with ThreadServer(app) as url:
        port = int(url.rsplit(":", 1)[1])
        for first, second in ((RIGHT, WRONG), (WRONG, RIGHT)):
            head = (f"POST /illuminants HTTP/1.1\r\nHost: x\r\nConnection: close\r\n{first[0]}: {first[1]}\r\n"
                    f"{second[0]}: {second[1]}\r\nContent-Type: multipart/form-data; boundary=b\r\n"
                    f"Content-Length: {len(form)}\r\n\r\n").encode()
            with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
                sock.sendall(head + form)
                answer = b""
                while chunk := sock.recv(65536):
                    answer += chunk
            assert answer.startswith(b"HTTP/1.1 400") and b"duplicate_authorization" in answer, answer[:300]
