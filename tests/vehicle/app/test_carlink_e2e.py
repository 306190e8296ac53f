"""The laptop and the car as two real processes on loopback: a simulator car (`manage.py drive`,
recording, a pilot driving) and the laptop's `vehicle car ...` commands.

Pull while the car records (a consistent snapshot), kill either side mid-transfer and resume, push
a hostile and a wrong-shape model, switch the pilot while the car drives (the loop goes on; the
car drops to user mode and says why), and a second laptop without the token gets nothing.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from fixtures.load import scaled
from fixtures.pilots import write_tub

from parts.tub import Tub
from parts.tub.transfer import staging_folder

pytest.importorskip("aiohttp")
pytest.importorskip("socketio")
torch = pytest.importorskip("torch")

ROOT = Path(__file__).resolve().parents[3]
TOKEN = "Kq3vT9xLm2Rw8ZpN4bYc"
ENV = dict(os.environ, PYTHONPATH=str(ROOT), SDL_VIDEODRIVER="dummy")
#: records of the tub the car holds from an earlier drive (big enough to be cut mid-stream)
OLD_RECORDS = 1500

pytestmark = pytest.mark.slow


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _model(path: Path, seed: int, frames: tuple[int, int] = (120, 160)) -> Path:
    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess

    torch.manual_seed(seed)
    shape = (*frames, 3)
    pre = Preprocess(crop=(40, 0, 0, 0), image_shape=shape)
    return save_model(path, create_model("linear", pre.output_shape(shape)), {"preprocess": pre.to_dict()})


class SimCar:
    """`manage.py drive --model models/a.pt --mode local` of a simulator car, in its own process."""

    def __init__(self, folder: Path) -> None:
        from vehicle.app.commands.createcar import create_car

        self.folder, self.port = folder, _free_port()
        create_car(folder, "simulator")
        (folder / "myconfig.py").write_text(f'WEB_CONTROL_PORT = {self.port}\nWEB_TOKEN = "{TOKEN}"\n')
        _model(folder / "models" / "a.pt", 0)
        write_tub(folder / "data" / "tub_0_old", n=OLD_RECORDS, sessions=1, size=(120, 160))
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/?token={TOKEN}"

    def start(self, pilot: bool = True) -> SimCar:
        """Drive (``pilot``: with a.pt in local mode; else a human's car, which loads no torch)."""
        self.log = self.folder / "drive.log"
        with_pilot = ["--model", "models/a.pt", "--mode", "local"] if pilot else []
        command = [sys.executable, "manage.py", "drive", *with_pilot]
        with open(self.log, "a") as log:  # a file, not a pipe: a full pipe would block the car
            self.proc = subprocess.Popen(command, cwd=self.folder, env=ENV, stdout=subprocess.DEVNULL, stderr=log)
        self.wait(lambda s: s["loops"] > 5, "the car to drive")
        return self

    def status(self) -> dict:
        from vehicle.app.carlink.client import CarClient, parse_address

        return CarClient(parse_address(self.url)).status()

    def wait(self, cond, what: str, timeout: float = 60.0) -> dict:
        from vehicle.app.carlink.client import CarLinkError

        end = time.monotonic() + scaled(timeout)
        while True:
            assert self.proc is not None and self.proc.poll() is None, self.log.read_text()[-3000:]
            try:
                status = self.status()
                if cond(status):
                    return status
            except CarLinkError:
                pass  # not listening yet
            assert time.monotonic() < end, f"timed out waiting for {what}"
            time.sleep(0.1)

    def record(self) -> None:
        """Press the page's record button (the first browser drives; recording alone arms no dead-man)."""
        import asyncio

        import socketio

        async def press() -> dict:
            async with socketio.AsyncSimpleClient() as sio:
                await sio.connect(f"http://127.0.0.1:{self.port}", auth={"token": TOKEN}, transports=["websocket"])
                return await sio.call("set", {"recording": True}, timeout=10)

        assert asyncio.run(press()) == {"ok": True}

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(30)

    def stop(self) -> str:
        assert self.proc is not None
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait(60)
        return self.log.read_text()


def vehicle(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "vehicle.app.cli", "car", *args], cwd=cwd, env=ENV,
                          capture_output=True, text=True, timeout=scaled(120))


def tub_records(path: Path, end: int | None = None) -> dict[int, dict]:
    """index -> record (image bytes in place of file names, session ids left out) below ``end``."""
    tub = Tub(path, read_only=True, log_problems=False)
    out = {}
    for i, rec in tub.records():
        if end is not None and i >= end:
            continue
        rec = {k: v for k, v in rec.items() if k != "_session_id"}
        rec["cam/image_array"] = (path / "images" / rec["cam/image_array"]).read_bytes()
        out[i] = rec
    tub.close()
    return out


@pytest.fixture(scope="module")
def car(tmp_path_factory):
    car = SimCar(tmp_path_factory.mktemp("carlink") / "car").start()
    yield car
    car.kill()


def _recording_tub(car: SimCar) -> Path:
    tubs = [p for p in (car.folder / "data").iterdir() if p.name.startswith("tub_") and p.name != "tub_0_old"]
    assert len(tubs) == 1, tubs
    return tubs[0]


def test_pull_while_the_car_records_is_a_consistent_snapshot(car, tmp_path):
    car.record()
    car.wait(lambda s: (s["records"] or 0) >= 40, "40 records")
    tub = _recording_tub(car)
    done = vehicle("pull", car.url, "--into", "laptop", "--tub", tub.name, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    pulled = Path("laptop") / f"car_{tub.name}"  # as the command prints it
    shown, pulled = pulled, tmp_path / pulled
    first = Tub(pulled, read_only=True)
    end = first.current_index
    first.close()
    assert end >= 40
    # every record the snapshot held, as the car has it (the car went on recording meanwhile)
    assert tub_records(pulled) == tub_records(tub, end)
    assert f"{shown}: {end} records pulled (new tub)" in done.stdout
    assert not (tmp_path / "laptop" / "car_tub_0_old").exists()  # only the tub asked for

    car.wait(lambda s: s["records"] >= end + 10, "10 more records")
    again = vehicle("pull", car.url, "--into", "laptop", "--tub", tub.name, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    second = Tub(pulled, read_only=True)
    new_end = second.current_index
    second.close()
    assert new_end >= end + 10
    assert f"{shown}: {new_end - end} records pulled" in again.stdout  # only what the laptop lacked
    assert tub_records(pulled) == tub_records(tub, new_end)


def test_a_second_laptop_without_the_token_gets_nothing(car, tmp_path):
    bare = f"http://127.0.0.1:{car.port}/"
    # every route, each without and with a wrong token: tests/parts/web/test_carlink.py; here the commands
    for args in (("pull", bare, "--into", "other"), ("use", bare, "a.pt", "--token", "wrong-token-123456")):
        done = vehicle(*args, cwd=tmp_path)
        assert done.returncode == 2, (args, done.stdout, done.stderr)
        assert "pairing token" in done.stderr and "Traceback" not in done.stderr
        assert done.stderr.count("\n") == 1  # one line
    assert not (tmp_path / "other").exists()


def test_hostile_and_wrong_shape_models_are_refused_in_one_line(car, tmp_path):
    class Evil:
        def __reduce__(self):
            return (os.system, ("touch pwned",))

    torch.save({"format": "vehicle-pilot", "state_dict": Evil()}, tmp_path / "evil.pt")
    _model(tmp_path / "wide.pt", 2, frames=(160, 320))
    for name, why in (("evil.pt", "pickled Python objects"), ("wide.pt", "320")):
        done = vehicle("push", car.url, name, "--use", cwd=tmp_path)
        assert done.returncode == 2, done.stdout
        assert f"{name} refused" in done.stderr and why in done.stderr, done.stderr
        assert "Traceback" not in done.stderr and done.stderr.count("\n") == 1
        assert not (car.folder / "models" / name).exists()
    assert not (car.folder / "pwned").exists() and not (tmp_path / "pwned").exists()
    assert car.status()["pilot"] == "a.pt"


def test_switching_the_pilot_while_the_car_drives(car, tmp_path):
    before = car.wait(lambda s: s["mode"] == "local", "the pilot to drive")
    assert before["pilot"] == "a.pt"
    _model(tmp_path / "b.pt", 1)
    done = vehicle("push", car.url, "b.pt", "--use", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "the car's pilot is now b.pt" in done.stdout
    after = car.status()
    assert (after["pilot"], after["mode"], after["pilot_error"]) == ("b.pt", "user", None)
    assert "choose a pilot mode" in after["notice"]  # the page says why the car stopped
    assert after["loops"] > before["loops"]  # the loop went on through the load
    assert (car.folder / "models" / "b.pt").read_bytes() == (tmp_path / "b.pt").read_bytes()
    assert vehicle("use", car.url, "b.pt", cwd=tmp_path).stdout.strip() == "the car already drives b.pt"
    missing = vehicle("use", car.url, "nope.pt", cwd=tmp_path)
    assert missing.returncode == 2 and "the car has no model nope.pt: push it first" in missing.stderr


KILL_AFTER = """
import os, signal, sys
from pathlib import Path
from vehicle.app.carlink.client import CarClient, parse_address
from vehicle.app.carlink.pull import pull_all

def progress(p):
    if p["done"] >= 600:  # past the first commit (200 records)
        os.kill(os.getpid(), signal.SIGKILL)

pull_all(CarClient(parse_address(sys.argv[1])), Path("laptop"), ["tub_0_old"], progress)
"""


def test_a_laptop_killed_mid_pull_leaves_no_tub_and_resumes(car, tmp_path):
    killed = subprocess.run([sys.executable, "-c", KILL_AFTER, car.url], cwd=tmp_path, env=ENV,
                            capture_output=True, text=True, timeout=scaled(120))
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    shown = Path("laptop") / "car_tub_0_old"
    target = tmp_path / shown
    assert not target.exists()
    staged = Tub(staging_folder(target), read_only=True)
    have = staged.current_index
    staged.close()
    assert 200 <= have < OLD_RECORDS
    done = vehicle("pull", car.url, "--into", "laptop", "--tub", "tub_0_old", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert f"{shown}: {OLD_RECORDS - have} records pulled (new tub)" in done.stdout
    assert tub_records(target) == tub_records(car.folder / "data" / "tub_0_old")


def test_the_car_killed_mid_pull_then_restarted_resumes(car, tmp_path):
    from parts.tub.transfer import TransferError
    from vehicle.app.carlink.client import CarClient, parse_address
    from vehicle.app.carlink.pull import pull_all

    def kill_the_car(p: dict) -> None:
        car.kill()  # the first record is in; the rest is still on the car

    with pytest.raises(TransferError, match="run the pull again to resume"):
        pull_all(CarClient(parse_address(car.url)), tmp_path / "laptop", ["tub_0_old"], kill_the_car)
    target = tmp_path / "laptop" / "car_tub_0_old"
    assert not target.exists()
    staged = Tub(staging_folder(target), read_only=True)
    have = staged.current_index
    staged.close()
    assert 1 <= have < OLD_RECORDS
    car.start(pilot=False)
    (report,) = pull_all(CarClient(parse_address(car.url)), tmp_path / "laptop", ["tub_0_old"])
    assert (report.start, report.received, report.created) == (have, OLD_RECORDS - have, True)
    assert tub_records(target) == tub_records(car.folder / "data" / "tub_0_old")
    err = car.stop()
    assert "throttle set to neutral" in err and "Traceback" not in err
    shutil.rmtree(tmp_path / "laptop")
