"""The page is served; no request path reads a file outside the served folder."""

from __future__ import annotations

import asyncio
import os

import pytest

from parts.web.server import STATIC_DIR, static_file


async def raw_get(port: int, path: str) -> tuple[int, bytes]:
    """Send the request path exactly as given (no client-side normalisation)."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n".encode())
    await writer.drain()
    data = await reader.read()
    writer.close()
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split()[1]), body


def test_page_and_assets_are_served(web, arun):
    async def main():
        status, body = await raw_get(web.port, "/")
        assert status == 200 and b"<canvas id=\"cam\"" in body
        status, body = await raw_get(web.port, "/static/sio.js")
        assert status == 200 and b"class SioClient" in body
        status, body = await raw_get(web.port, "/static/app.js")
        assert status == 200 and b"new SioClient" in body
        status, body = await raw_get(web.port, "/static/style.css")
        assert status == 200 and b".estop" in body
        status, body = await raw_get(web.port, "/favicon.ico")  # issue 21: it was a 404
        assert status == 200 and body.startswith(b"<svg")

    arun(main())


TRAVERSALS = [
    "/static/../server.py", "/static/%2e%2e/server.py", "/static/..%2fserver.py",
    "/static/%2e%2e%2fserver.py", "/static/..%5cserver.py", "/static/....//server.py",
    "/static//etc/passwd", "/static/%2fetc%2fpasswd", "/static/../../../../etc/passwd",
    "/static/%2e%2e/%2e%2e/%2e%2e/%2e%2e/etc/passwd", "/../../etc/passwd", "/%2e%2e/etc/passwd",
    "/static/.%2e/.%2e/vehicle/config.py", "/static/app.js%00.png", "/static/",
    "/static/.hidden", "/etc/passwd", "/server.py", "/static/..;/server.py",
]


@pytest.mark.parametrize("path", TRAVERSALS)
def test_path_traversal_is_refused(web, arun, path):
    status, body = arun(raw_get(web.port, path))
    assert status in (400, 403, 404), (path, status)
    assert b"root:" not in body and b"import" not in body and b"def " not in body


def test_static_file_resolution(tmp_path):
    root = tmp_path / "static"
    root.mkdir()
    (root / "ok.js").write_text("x")
    (tmp_path / "secret.txt").write_text("secret")
    (root / "link.txt").symlink_to(tmp_path / "secret.txt")
    (root / "sub").mkdir()
    assert static_file(root, "ok.js") == (root / "ok.js").resolve()
    for bad in ("../secret.txt", "link.txt", "sub", "sub/../../secret.txt", "", "/",
                "..\\secret.txt", "ok.js\x00", ".", "nothing.js", str(tmp_path / "secret.txt")):
        assert static_file(root, bad) is None, bad
    assert static_file(STATIC_DIR, "index.html") is not None
    assert os.path.isfile(STATIC_DIR / "app.js")
