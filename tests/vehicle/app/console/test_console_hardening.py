"""Issue 27 items 8, 14 and 17: the console serves no file from outside a tub (symlinks), slows and
logs repeated wrong tokens, and answers hostile JSON with a one-line 400."""

from __future__ import annotations

import json
import logging
import urllib.error
import urllib.request

from test_console_api import request


def _first_dataset(port):
    datasets = json.loads(request(port, "/api/datasets")[2])
    return min(datasets, key=lambda d: d["id"])


def test_a_symlinked_image_that_leaves_the_tub_is_not_served(console, tmp_path):
    port = console.port
    ds = _first_dataset(port)
    fields = json.loads(request(port, f"/api/datasets/{ds['id']}/records/0")[2])["fields"]
    image = console.datasets.get(ds["id"]).path / "images" / fields["cam/image_array"]
    secret = tmp_path / "id_rsa"
    secret.write_bytes(b"-----BEGIN OPENSSH PRIVATE KEY-----secret")
    good = image.read_bytes()
    image.unlink()
    image.symlink_to(secret)
    status, _, body = request(port, f"/api/datasets/{ds['id']}/images/0")
    assert status in (403, 404) and b"PRIVATE KEY" not in body
    assert b"outside" in body
    # a link to another image of the same tub stays served (tools may deduplicate that way)
    other = image.with_name("copy.jpg")
    other.write_bytes(good)
    image.unlink()
    image.symlink_to(other.name)
    status, _, body = request(port, f"/api/datasets/{ds['id']}/images/0")
    assert status == 200 and body == good


def test_a_symlinked_catalog_that_leaves_the_tub_is_not_read(console, tmp_path):
    port = console.port
    ds = _first_dataset(port)
    tub = console.datasets.get(ds["id"]).path
    secret = tmp_path / "secret.json"
    secret.write_text(json.dumps({"_index": 0, "_timestamp_ms": 1, "password": "hunter2-secret"}) + "\n")
    catalog = tub / "catalog_0.catalog"
    catalog.unlink()
    catalog.symlink_to(secret)
    for path in (f"/api/datasets/{ds['id']}/records/0", f"/api/datasets/{ds['id']}", "/api/datasets",
                 f"/api/datasets/{ds['id']}/series"):
        status, _, body = request(port, path)
        assert b"hunter2" not in body, path
    status, _, body = request(port, f"/api/datasets/{ds['id']}/records/0")
    assert status == 403 and b"outside" in body and b"catalog_0.catalog" in body


def test_deeply_nested_json_is_a_400_with_one_line(console, caplog):
    caplog.set_level(logging.DEBUG)
    body = b"[" * 100_000 + b"]" * 100_000
    req = urllib.request.Request(f"http://127.0.0.1:{console.port}/api/train/validate", data=body, method="POST",
                                 headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=30) as resp:
            status, text = resp.status, resp.read()
    except urllib.error.HTTPError as exc:
        status, text = exc.code, exc.read()
    assert status == 400, text
    message = json.loads(text)["error"]
    assert "nested" in message and "\n" not in message
    assert not [r for r in caplog.records if r.exc_info or "Traceback" in r.getMessage()]


def test_wrong_tokens_are_slowed_per_client_and_logged_throttled(console_factory, caplog):
    caplog.set_level(logging.INFO)
    app = console_factory(token="secret-token-1")
    statuses = [request(app.port, "/api/datasets", headers={"X-Vehicle-Token": f"guess-{i}"})[0] for i in range(40)]
    # a few mistakes are forgiven, then the client must wait: guesses stop being checked
    assert statuses[:3] == [401, 401, 401]
    assert statuses[-1] == 429 and statuses.count(401) <= 10
    status, headers, body = request(app.port, "/api/datasets", headers={"X-Vehicle-Token": "guess-x"})
    assert status == 429 and int(headers["Retry-After"]) >= 1 and b"wait" in body
    # hardening item 18: the right token from the same address (a NAT) is never made to wait
    assert request(app.port, "/api/datasets", headers={"X-Vehicle-Token": "secret-token-1"})[0] == 200
    warnings = [r.getMessage() for r in caplog.records if "pairing token" in r.getMessage()]
    assert 1 <= len(warnings) <= 3 and "127.0.0.1" in warnings[0]
