"""The console's server without a browser: the pairing token, Host and Origin rules, JSON errors, the
event stream, and the job queue (one at a time, cancel, restart)."""

from __future__ import annotations

import http.client
import json
import sqlite3
import time
import urllib.error
import urllib.request

import pytest
from fixtures.load import scaled


def request(port, path, method="GET", body=None, headers=None):
    """(status, headers, body) of one request to the console."""
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=data, method=method,
                                 headers={**({"Content-Type": "application/json"} if body is not None else {}),
                                          **(headers or {})})
    try:
        with urllib.request.urlopen(req, timeout=scaled(30)) as resp:
            return resp.status, resp.headers, resp.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers, exc.read()


def test_off_loopback_rules_need_the_token(console_factory):
    app = console_factory(token="secret-token-1")
    status, _, body = request(app.port, "/api/datasets")
    assert status == 401 and b"pairing token" in body
    assert request(app.port, "/api/datasets", headers={"X-Vehicle-Token": "wrong-token"})[0] == 401
    assert request(app.port, "/api/datasets", headers={"X-Vehicle-Token": "secret-token-1"})[0] == 200
    assert request(app.port, "/")[0] == 401
    # the paired URL sets the cookie and sends the browser on to "/": the token leaves the address bar
    conn = http.client.HTTPConnection("127.0.0.1", app.port, timeout=scaled(30))
    conn.request("GET", "/?token=secret-token-1")
    resp = conn.getresponse()
    cookie = resp.headers["Set-Cookie"]
    assert resp.status == 303 and resp.headers["Location"] == "/"
    assert "vehicle_console_token=secret-token-1" in cookie and "HttpOnly" in cookie and "SameSite=Strict" in cookie
    conn.close()
    status, _, body = request(app.port, "/", headers={"Cookie": "vehicle_console_token=secret-token-1"})
    assert status == 200 and b"<html" in body.lower()
    assert request(app.port, "/?token=wrong-token")[0] == 401
    assert request(app.port, "/api/datasets", headers={"Cookie": "vehicle_console_token=secret-token-1"})[0] == 200
    # the page itself and its static files hold no data: served without the token
    assert request(app.port, "/static/console.js")[0] == 200
    assert request(app.port, "/static/vendor/uPlot.iife.min.js")[0] == 200
    assert request(app.port, "/static/../server.py")[0] == 404


def test_loopback_refuses_other_host_names_and_other_sites(console):
    port = console.port
    assert request(port, "/api/datasets")[0] == 200
    assert request(port, "/api/datasets", headers={"Host": f"localhost:{port}"})[0] == 200
    status, _, body = request(port, "/api/datasets", headers={"Host": f"evil.example:{port}"})  # DNS rebinding
    assert status == 421 and b"unexpected Host" in body
    assert request(port, "/api/datasets", headers={"Host": f"[::1]:{port}"})[0] == 200
    assert request(port, "/api/datasets", headers={"Host": f"localhost.evil.example:{port}"})[0] == 421
    assert request(port, "/api/datasets", headers={"Host": ""})[0] in (400, 421)
    status, _, body = request(port, "/api/datasets", "POST", {"action": "create", "name": "x"},
                              headers={"Origin": "http://evil.example"})
    assert status == 403 and not (console.datasets.data_path / "x").exists()
    status, _, _ = request(port, "/api/datasets", "POST", {"action": "create", "name": "x"},
                           headers={"Origin": f"http://127.0.0.1:{port}"})
    assert status == 201 and (console.datasets.data_path / "x").is_dir()  # the tub appears with its first record


def test_errors_are_json_with_the_field(console):
    port = console.port
    status, _, body = request(port, "/api/jobs/train", "POST", {"datasets": [], "name": "", "hyper": {"epochs": "0"}})
    errors = json.loads(body)["errors"]
    assert status == 400 and set(errors) == {"datasets", "name", "epochs"}
    assert errors["epochs"] == "must be a whole number ≥ 1 (got '0'): training needs at least one epoch"
    req = urllib.request.Request(f"http://127.0.0.1:{port}/api/datasets", data=b"name=x", method="POST",
                                 headers={"Content-Type": "application/x-www-form-urlencoded"})
    with pytest.raises(urllib.error.HTTPError) as info:
        urllib.request.urlopen(req, timeout=scaled(10))
    assert info.value.code == 415
    assert request(port, "/api/datasets/999")[0] == 404
    assert request(port, "/api/models/nothing")[0] == 404
    assert request(port, "/api/jobs/abc")[0] == 400


def test_the_event_stream_starts_with_the_jobs(console):
    with urllib.request.urlopen(f"http://127.0.0.1:{console.port}/api/events", timeout=scaled(10)) as resp:
        assert resp.headers["Content-Type"] == "text/event-stream"
        line = resp.readline().decode()
    hello = json.loads(line.removeprefix("data: "))
    assert hello["event"] == "hello" and hello["jobs"] == []


def _wait(port, job, cond, timeout=120.0):
    end = time.monotonic() + scaled(timeout)
    while True:
        state = json.loads(request(port, f"/api/jobs/{job}")[2])
        if cond(state):
            return state
        if time.monotonic() > end:
            raise AssertionError(f"job {job} stuck: {state['status']} {state['message']} {state['log'][-3:]}")
        time.sleep(0.2)


@pytest.mark.slow
def test_jobs_run_one_at_a_time_and_cancel(console):
    port = console.port
    ids = [d["id"] for d in json.loads(request(port, "/api/datasets")[2])]
    hyper = {"epochs": "100000", "steps_per_epoch": "1", "val_steps": "1", "batch_size": "4", "early_stop": "false"}
    a = json.loads(request(port, "/api/jobs/train", "POST", {"datasets": ids, "name": "first", "hyper": hyper})[2])
    b = json.loads(request(port, "/api/jobs/train", "POST", {"datasets": ids[:1], "name": "second",
                                                             "hyper": hyper})[2])
    status, _, body = request(port, "/api/jobs/train", "POST", {"datasets": ids, "name": "first", "hyper": hyper})
    assert status == 400 and "queued training already writes 'first'" in json.loads(body)["errors"]["name"]
    _wait(port, a["id"], lambda s: len(s["epochs"]) >= 1)
    assert json.loads(request(port, f"/api/jobs/{b['id']}")[2])["status"] == "queued"
    # the running training's tubs are busy: the datasets page leaves them alone
    status, _, body = request(port, f"/api/datasets/{ids[0]}/delete", "POST")
    assert status == 409 and b"queued or running job" in body
    assert request(port, f"/api/jobs/{b['id']}/cancel", "POST")[0] == 200
    assert json.loads(request(port, f"/api/jobs/{b['id']}")[2])["status"] == "cancelled"
    assert request(port, f"/api/jobs/{a['id']}/cancel", "POST")[0] == 200
    done = _wait(port, a["id"], lambda s: s["status"] not in ("running", "cancelling"))
    assert done["status"] == "cancelled" and done["result"]["model"] == "first"
    assert console.db.get("first").metrics["cancelled"] is True
    assert not (console.cfg.path("MODELS_PATH") / "second.pt").exists()
    assert request(port, f"/api/jobs/{a['id']}/cancel", "POST")[0] == 409


def test_a_job_left_running_by_a_stopped_console_is_marked_interrupted(console_factory, config):
    first = console_factory()
    first.close()
    with sqlite3.connect(first.db.db_path) as conn:
        conn.execute("INSERT INTO console_jobs (kind, status, title, params, created) "
                     "VALUES ('train', 'running', 'train x', '{}', '2026-01-01T00:00:00+00:00')")
    app = console_factory()
    [job] = json.loads(request(app.port, "/api/jobs")[2])
    assert job["status"] == "interrupted" and "console stopped" in job["message"]


def test_the_console_command_checks_its_car(tmp_path, capsys):
    from vehicle.app.cli import main

    assert main(["console", "--car", str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err


def test_a_model_in_use_by_a_job_is_neither_deleted_nor_renamed(console, registered_model):
    """Deleting or renaming the model an evaluation drives, or a training starts from, would make the
    job fail at its end and lose its result: refused until the job is over."""
    port = console.port
    registered_model("busy")
    registered_model("base")
    ids = [d["id"] for d in json.loads(request(port, "/api/datasets")[2])]
    hold = {"epochs": "100000", "steps_per_epoch": "1", "val_steps": "1", "batch_size": "4", "early_stop": "false"}
    first = json.loads(request(port, "/api/jobs/train", "POST", {"datasets": ids, "name": "first", "hyper": hold})[2])
    ev = json.loads(request(port, "/api/jobs/evaluate", "POST", {"model": "busy", "tracks": "101", "laps": 1})[2])
    tr = json.loads(request(port, "/api/jobs/train", "POST", {"datasets": ids, "name": "child", "transfer": "base",
                                                              "hyper": {"epochs": "1"}})[2])
    for name in ("busy", "base"):
        status, _, body = request(port, f"/api/models/{name}", "DELETE")
        assert status == 409 and f"job {ev['id'] if name == 'busy' else tr['id']}" in json.loads(body)["error"]
        status, _, body = request(port, f"/api/models/{name}", "PATCH", {"name": f"{name}2"})
        assert status == 409
        assert console.db.get(name).exists
    # a comment is harmless: allowed
    assert request(port, "/api/models/base", "PATCH", {"comment": "the parent"})[0] == 200
    for job in (ev, tr, first):
        request(port, f"/api/jobs/{job['id']}/cancel", "POST")
    _wait(port, first["id"], lambda s: s["status"] not in ("running", "cancelling"))
    assert request(port, "/api/models/busy", "DELETE")[0] == 200
    assert request(port, "/api/models/base", "PATCH", {"name": "base2"})[0] == 200


def test_dataset_ids_of_a_training_are_whole_numbers(console):
    ids = [d["id"] for d in json.loads(request(console.port, "/api/datasets")[2])]
    assert 1 in ids
    for bad in (True, 1.7, "1.0", None, [1]):  # JSON true or 1.7 is not dataset 1
        status, _, body = request(console.port, "/api/jobs/train", "POST", {"datasets": [bad], "name": "m"})
        assert status == 400 and "does not exist" in json.loads(body)["errors"]["datasets"], bad
    assert console.jobs.list() == []


def test_one_console_per_car_a_second_is_a_one_line_error_naming_the_first(console_factory):
    import os

    from vehicle.app.console.server import ConsoleBusyError

    first = console_factory()
    with pytest.raises(ConsoleBusyError) as info:
        console_factory()
    message = str(info.value)
    assert f"already running (process {os.getpid()}, http://127.0.0.1:{first.port}/)" in message
    assert "\n" not in message
    assert request(first.port, "/api/jobs")[0] == 200  # the first is untouched
    first.close()
    second = console_factory()  # the lock went with the first console
    assert request(second.port, "/api/jobs")[0] == 200


def test_a_console_that_cannot_listen_says_whether_the_port_or_the_address_is_wrong(console_factory):
    # acceptance: --host 10.99.99.99 (not this machine's) said "another program uses the port"
    import socket

    with pytest.raises(OSError, match=r"192\.0\.2\.1 is not an address of this machine; pass --host or set "
                                      r"CONSOLE_HOST"):
        console_factory(host="192.0.2.1")  # TEST-NET-1: never an address of a test machine
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(OSError, match=rf"port {port} is in use by another program .*; pass --port or set "
                                          "CONSOLE_PORT"):
            console_factory(port=port)
    assert request(console_factory().port, "/api/jobs")[0] == 200  # the car's lock was let go both times


def test_a_training_with_a_recipe_carries_its_settings_to_the_worker(console):
    from vehicle.app.console.worker import _config

    first = json.loads(request(console.port, "/api/datasets")[2])[0]["id"]  # registers the car's tubs
    status, _, body = request(console.port, "/api/jobs/train", "POST",
                              {"datasets": [first], "name": "by_recipe", "recipe": "udacity_bc"})
    assert status == 400 and "Did you mean 'udacity-bc'" in json.loads(body)["errors"]["recipe"]
    status, _, body = request(console.port, "/api/jobs/train", "POST",
                              {"datasets": [first], "name": "by_recipe", "recipe": "udacity-bc",
                               "hyper": {"epochs": "1"}})
    assert status == 201, body
    job = json.loads(body)
    params = console.jobs.get(job["id"]).params
    assert params["recipe"] == "udacity-bc" and params["model_type"] == "pilotnet"
    cfg = _config({"car": str(console.cfg.CAR_PATH), "myconfig": None, "params": params})
    assert cfg.PREPROCESS_NORMALIZE == "symmetric127" and cfg.TRAIN_FLIP_COPY  # from the recipe
    assert cfg.MAX_EPOCHS == 1  # the form's value wins
    request(console.port, f"/api/jobs/{job['id']}/cancel", "POST")
