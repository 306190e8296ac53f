"""Our simulator behind the Donkey protocol: a gym-donkeycar-style client, and our own client."""

from __future__ import annotations

import base64
import contextlib
import io
import json
import math
import re
import select
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fixtures.carpath import unity_cross_track_err
from fixtures.load import scaled
from PIL import Image

from parts.bridges import donkey_protocol as proto
from parts.bridges.donkey_client import DonkeySim
from parts.bridges.donkey_server import DonkeyServer, scene_names, seed_for_scene
from parts.bridges.errors import BridgeError
from parts.sim.expert import Expert
from parts.sim.simulator import SimCar
from vehicle.config import Config


@pytest.fixture(scope="module")
def server() -> Iterator[DonkeyServer]:
    with DonkeyServer(port=0, seeds=[5, 6]) as srv:
        yield srv


# -- a client that follows gym-donkeycar 1.3.1's documented sequence and semantics ------------------
def replace_float_notation(text: str) -> str:
    """gym-donkeycar's repair of Unity's comma floats: ``"key":1,2`` -> ``"key":1.2``."""
    return re.sub(r'("[A-Za-z_]+":\s*-?\d+),(\d+)', r"\1.\2", text)


class GymStyleClient:
    """SDClient + DonkeyUnitySimHandler as docs/simulators.md §3.5 describes them (not their code)."""

    def __init__(self, port: int, level: str = "generated_track", max_cte: float = 8.0) -> None:
        self.level, self.max_cte = level, max_cte
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.setblocking(False)
        self.msg: str | None = None  # lossy one-slot queue for control
        self.buffer = ""
        self.error: Exception | None = None
        self.loaded = False
        self.telemetry: dict[str, Any] = {}
        self.received_at = 0.0  # time of the last telemetry
        self.hit, self.cte, self.speed = "none", 0.0, 0.0
        self.lap_count, self.last_lap_time = 0, 0.0
        self.starting_line_index, self.lap_start = -1, None
        self.over = False
        self.running = True
        self.thread = threading.Thread(target=self.proc_msg, daemon=True)
        self.thread.start()

    # SDClient
    def proc_msg(self) -> None:
        while self.running:
            readable, writable, _ = select.select([self.sock], [self.sock], [], 0.01)
            if writable and self.msg is not None:
                self.sock.sendall(self.msg.encode())
                self.msg = None
            if readable:
                try:
                    data = self.sock.recv(1024 * 256)
                except BlockingIOError:
                    continue
                if not data:
                    return
                self.buffer += data.decode()
                start, end = self.buffer.find("{"), self.buffer.rfind("}\n")
                if start < 0 or end < 0:
                    continue
                chunk, self.buffer = self.buffer[start:end + 1], self.buffer[end + 2:]
                for part in chunk.split("\n"):
                    if len(part) <= 2:
                        continue
                    msg = json.loads(replace_float_notation(part))
                    if "msg_type" in msg:
                        self.on_msg_recv(msg)
            time.sleep(0.001)

    def queue_message(self, msg: dict[str, Any]) -> None:
        self.msg = json.dumps(msg)

    def blocking_send(self, msg: dict[str, Any]) -> None:
        self.sock.setblocking(True)
        self.sock.sendall(json.dumps(msg).encode())
        self.sock.setblocking(False)
        time.sleep(0.1)

    # handler
    def on_msg_recv(self, msg: dict[str, Any]) -> None:
        kind = msg["msg_type"]
        if kind == "scene_selection_ready":
            self.blocking_send({"msg_type": "get_scene_names"})
        elif kind == "scene_names":
            if self.level not in msg["scene_names"]:
                self.error = ValueError(f"{self.level} is not in the list of scenes")
            else:
                self.blocking_send({"msg_type": "load_scene", "scene_name": self.level})
        elif kind == "car_loaded":
            self.send_control(0, 0, brake=1.0)
            self.blocking_send({"msg_type": "car_config", "body_style": "donkey", "body_r": "128", "body_g": "128",
                                "body_b": "128", "car_name": "gym", "font_size": "100"})
            self.blocking_send({"msg_type": "cam_config", "img_w": "160", "img_h": "120", "img_d": "3",
                                "img_enc": "JPG", "fov": "0"})
            self.loaded = True
        elif kind == "telemetry":
            self.telemetry = msg
            self.hit, self.cte, self.speed = msg["hit"], msg["cte"], msg["speed"]
            self.received_at = time.monotonic()
            self.determine_episode_over()
        elif kind == "collision_with_starting_line":
            if self.lap_start is None or msg["starting_line_index"] != self.starting_line_index:
                self.starting_line_index, self.lap_start = msg["starting_line_index"], msg["timeStamp"]
            else:
                self.last_lap_time = msg["timeStamp"] - self.lap_start
                self.lap_start = msg["timeStamp"]
                self.lap_count += 1

    def determine_episode_over(self) -> None:
        if abs(self.cte) > 2 * self.max_cte:
            pass  # a spawn glitch, ignored
        elif abs(self.cte) > self.max_cte or self.hit != "none":
            self.over = True

    def send_control(self, steer: float, throttle: float, brake: float = 0.0) -> None:
        self.queue_message({"msg_type": "control", "steering": str(steer), "throttle": str(throttle),
                            "brake": str(brake)})

    def observe(self, timeout: float = 5.0) -> dict[str, Any]:
        last = self.received_at
        end = time.monotonic() + scaled(timeout)
        while self.received_at == last and time.monotonic() < end:
            time.sleep(0.001)
        assert self.received_at != last, "no telemetry"
        return self.telemetry

    def calc_reward(self) -> float:
        if self.over:
            return -1.0
        if self.hit != "none":
            return -2.0
        t = self.telemetry
        yaw = math.radians(t["yaw"])  # heading projection of the velocity (pitch, roll are 0 here)
        forward_vel = t["vel_x"] * math.sin(yaw) + t["vel_z"] * math.cos(yaw)
        return (1.0 - abs(self.cte) / self.max_cte) * forward_vel if forward_vel > 0 else forward_vel

    def reset(self) -> dict[str, Any]:
        self.send_control(0, 0, 1.0)
        time.sleep(0.1)
        self.blocking_send({"msg_type": "reset_car"})
        time.sleep(1.0)
        self.over, self.hit = False, "none"
        self.lap_count, self.lap_start = 0, None
        self.send_control(0, 0, 1.0)
        time.sleep(0.1)
        return self.observe()

    def step(self, steer: float, throttle: float) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        self.send_control(steer, throttle)
        obs = self.observe()
        info = {"cte": self.cte, "speed": self.speed, "hit": self.hit, "lap_count": self.lap_count,
                "last_lap_time": self.last_lap_time, "pos": (obs["pos_x"], obs["pos_y"], obs["pos_z"])}
        return obs, self.calc_reward(), self.over, False, info

    def close(self) -> None:
        self.blocking_send({"msg_type": "exit_scene"})
        self.running = False
        self.thread.join(2)
        self.sock.close()

    def wait_loaded(self, timeout: float = 10.0) -> None:
        end = time.monotonic() + scaled(timeout)
        while not self.loaded and self.error is None and time.monotonic() < end:
            time.sleep(0.01)


def test_gym_style_client_runs_episodes(server: DonkeyServer) -> None:
    env = GymStyleClient(server.port, level="generated_track", max_cte=8.0)
    try:
        env.wait_loaded()
        assert env.loaded and env.error is None
        obs = env.reset()
        assert obs["speed"] == pytest.approx(0.0, abs=1e-6) and abs(obs["cte"]) < 0.01
        image = base64.b64decode(obs["image"])
        assert image[:2] == b"\xff\xd8"  # a JPEG, 160x120 asked with cam_config
        rewards, over, info = [], False, {}
        for _ in range(400):  # full throttle, wheels straight: the road bends away, the car leaves it
            _, reward, over, truncated, info = env.step(0.0, 1.0)
            rewards.append(reward)
            assert truncated is False
            if over:
                break
        assert over and info["hit"] == "off_track"  # gym's max_cte 8 is metres here: the hit ends it
        assert rewards[-1] == -1.0 and max(rewards) > 0
        assert env.lap_start is not None and env.lap_count == 0  # the start crossing began the clock
        obs = env.reset()
        assert abs(obs["cte"]) < 0.01 and obs["speed"] == pytest.approx(0.0, abs=1e-6)
        assert not env.over
        _, reward, over, _, _ = env.step(0.0, 0.5)
        assert not over
    finally:
        env.close()


def test_gym_style_client_gets_every_scene_of_the_gym_ids(server: DonkeyServer) -> None:
    env = GymStyleClient(server.port, level="no_such_level")
    try:
        env.wait_loaded(3)  # (scaled) long enough for the error, not for a load
        assert isinstance(env.error, ValueError) and not env.loaded
    finally:
        env.close()
    assert set(proto.GYM_SCENES.values()) <= set(scene_names([5]))
    assert seed_for_scene("generated_road", [5, 6]) == 5 and seed_for_scene("warehouse", [5, 6]) == 6
    assert seed_for_scene("track_42", [5]) == 42 and seed_for_scene("nope", [5]) is None


# -- our client against our server --------------------------------------------------------------
class ShadowExpert:
    """The built-in expert driving from telemetry only (pose from pos_x/pos_z/yaw)."""

    def __init__(self, seed: int) -> None:
        self.shadow = SimCar.from_config(Config.defaults(), seeds=[seed])
        self.expert = Expert(self.shadow, speed=1.5)

    def command(self, extra: dict[str, Any], pos: tuple[float, float], speed: float) -> tuple[float, float]:
        st = self.shadow.car.state
        st.x, st.y = pos
        st.heading = math.radians(90.0 - extra["yaw"])
        st.speed = speed
        return self.expert.command()


def test_our_client_laps_our_server_in_synchronous_steps(server: DonkeyServer) -> None:
    sim = DonkeySim(port=server.port, scene="track_5", synchronous=True, time_step=0.05, connect_timeout_s=scaled(3),
                    timeout_s=scaled(1))
    driver = ShadowExpert(5)
    try:
        out = dict(zip(DonkeySim.OUTPUTS, sim.run(0.0, 0.0, False), strict=True))
        session = next(s for s in server.sessions if s.alive and s.scene == "track_5")
        t0 = out["sim/time"]
        for step in range(1, 2000):
            angle, throttle = driver.command(out["sim/extra"], out["sim/pos"], out["sim/speed"])
            out = dict(zip(DonkeySim.OUTPUTS, sim.run(angle, throttle, False), strict=True))
            # one step per control, in simulated time
            assert out["sim/time"] == pytest.approx(t0 + 0.05 * step, abs=1e-6)
            assert out["sim/cte"] == pytest.approx(session.sim.frame.cte, abs=1e-9)  # our sign both ends
            if out["sim/lap"] == 1:
                break
        assert out["sim/lap"] == 1 and out["sim/off_track"] is False
        # gym's rule: from the first crossing (the car drove off the line at the first step) to the next
        assert out["sim/lap_time"] == pytest.approx(out["sim/time"] - (t0 + 0.05), abs=1e-6)
        assert session.sim.tracker.laps == 1
        assert out["cam/image_array"].shape == (120, 160, 3) and out["cam/image_array"].std() > 10
        assert 0 <= out["sim/progress"] < 0.1
    finally:
        sim.shutdown()
    assert session.synchronous and session.telemetry_sent == session.steps + 1  # + the first observation


def test_several_clients_each_with_their_own_car_and_track(server: DonkeyServer) -> None:
    a = DonkeySim(port=server.port, scene="track_5", connect_timeout_s=scaled(3), timeout_s=scaled(1)).start()
    b = DonkeySim(port=server.port, scene="track_6", connect_timeout_s=scaled(3), timeout_s=scaled(1)).start()
    try:
        for _ in range(30):
            out_a = dict(zip(DonkeySim.OUTPUTS, a.run_threaded(0.0, 0.6, False), strict=True))
            out_b = dict(zip(DonkeySim.OUTPUTS, b.run_threaded(0.0, 0.0, False), strict=True))
            time.sleep(0.05)
        seeds = {s.sim.seed for s in server.sessions if s.alive and s.sim is not None}
        assert {5, 6} <= seeds
    finally:
        a.shutdown()
        b.shutdown()
    assert out_a["cam/ok"] and out_b["cam/ok"]
    assert out_a["sim/speed"] > 0.5 and out_b["sim/speed"] == pytest.approx(0.0, abs=1e-6)
    assert not np.array_equal(out_a["cam/image_array"], out_b["cam/image_array"])


def test_exit_scene_regen_road_and_node_position(server: DonkeyServer) -> None:
    with socket.create_connection(("127.0.0.1", server.port), timeout=scaled(5)) as s:
        stream = proto.JsonStream()

        def expect(kind: str) -> dict[str, Any]:
            end = time.monotonic() + scaled(5)
            while time.monotonic() < end:
                for msg in stream.feed(s.recv(1 << 16)):
                    if msg["msg_type"] == kind:
                        return msg
            raise AssertionError(f"no {kind}")

        def send(msg_type: str, **fields: Any) -> None:
            s.sendall(proto.client_message(msg_type, **fields))
            time.sleep(0.05)

        expect("scene_selection_ready")
        send("load_scene", scene_name="track_6")
        expect("car_loaded")
        assert expect("telemetry")["totalNodes"] > 10
        send("regen_road", road_style="0", rand_seed="9", turn_increment="1")
        send("node_position", index="0")
        node = expect("node_position")
        session = next(x for x in server.sessions if x.alive and x.scene == "track_9")
        x, y, _ = session.sim.track.pose_at(0.0)
        assert (node["pos_x"], node["pos_z"]) == pytest.approx((x, y), abs=0.05)
        send("exit_scene")
        expect("scene_selection_ready")
        send("get_protocol_version")
        assert expect("protocol_version")["version"] == "2"


def test_client_sees_a_missing_scene(server: DonkeyServer) -> None:
    with pytest.raises(BridgeError, match="no scene 'mars'"):
        DonkeySim(port=server.port, scene="mars", connect_timeout_s=scaled(3)).start()


def test_port_in_use_is_one_clear_error(server: DonkeyServer) -> None:
    with pytest.raises(BridgeError, match=rf"cannot listen on 127.0.0.1:{server.port} .*--port"):
        DonkeyServer(port=server.port).start()


# -- review fixes: what a client may send, and the CTE the real simulator computes -----------------
class RawClient:
    """A bare TCP client of the protocol, for messages no well-behaved client sends."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=scaled(5))
        self.stream = proto.JsonStream()

    def expect(self, kind: str, timeout: float = 5.0) -> dict[str, Any]:
        end = time.monotonic() + scaled(timeout)
        while time.monotonic() < end:
            data = self.sock.recv(1 << 16)
            if not data:
                raise AssertionError(f"the server closed the connection before {kind}")
            for msg in self.stream.feed(data):
                if msg["msg_type"] == kind:
                    return msg
        raise AssertionError(f"no {kind}")

    def load(self, scene: str = "track_5", synchronous: bool = True) -> None:
        """Menu -> scene loaded (-> step mode, 0.05 s per step)."""
        self.expect("scene_selection_ready")
        self.send("load_scene", scene_name=scene)
        self.expect("car_loaded")
        if synchronous:
            self.send("step_mode", step_mode="synchronous", time_step="0.05")

    def send(self, msg_type: str, **fields: Any) -> None:
        self.sendraw(proto.client_message(msg_type, **fields))

    def sendraw(self, data: bytes) -> None:
        self.sock.sendall(data)
        time.sleep(0.05)  # one message per chunk, as the simulator needs

    def drain(self, quiet_s: float = 0.3) -> None:
        """Read (and drop) what arrives until nothing has for ``quiet_s``."""
        self.sock.settimeout(quiet_s)
        try:
            while self.sock.recv(1 << 16):
                pass
        except TimeoutError:
            pass
        finally:
            self.sock.settimeout(scaled(5))
        self.stream = proto.JsonStream()

    def closed_within(self, timeout: float) -> bool:
        """Whether the server closes the connection within ``timeout`` s (what it sends is read)."""
        end = time.monotonic() + scaled(timeout)
        self.sock.settimeout(0.1)
        while time.monotonic() < end:
            try:
                if not self.sock.recv(1 << 16):
                    return True
            except TimeoutError:
                continue
            except OSError:
                return True
        return False

    def close(self) -> None:
        self.sock.close()


def test_unity_cross_track_err_is_positive_right_of_the_path() -> None:
    # driving along +z (Unity: x right, z forward, y up): a car at x > 0 is right of the path
    assert unity_cross_track_err((0.0, 0.0), (0.0, 1.0), (0.5, 0.3)) == pytest.approx(0.5)
    assert unity_cross_track_err((0.0, 0.0), (0.0, 1.0), (-0.25, 0.3)) == pytest.approx(-0.25)


def test_telemetry_cte_is_the_simulators_cross_track_error(server: DonkeyServer) -> None:
    """Our cte has the sign and size CarPath computes from the path nodes and the car's position."""
    c = RawClient(server.port)
    try:
        c.load()
        for steering in (0.6, -0.6):  # off the centre line to the right, then to the left
            for _ in range(12):
                c.send("control", steering=str(steering), throttle="0.5", brake="0")
                tel = c.expect("telemetry")
            node = tel["activeNode"]
            c.send("node_position", index=str(node))
            a = c.expect("node_position")
            c.send("node_position", index=str((node + 1) % tel["totalNodes"]))
            b = c.expect("node_position")
            expected = unity_cross_track_err((a["pos_x"], a["pos_z"]), (b["pos_x"], b["pos_z"]),
                                             (tel["pos_x"], tel["pos_z"]))
            assert abs(tel["cte"]) > 0.02
            assert tel["cte"] == pytest.approx(expected, abs=0.02)
            assert (tel["cte"] > 0) == (steering > 0)  # Donkey steering > 0 turns right
    finally:
        c.close()


def test_cam_config_is_clamped_to_the_frame_limits(server: DonkeyServer) -> None:
    from parts.bridges.frames import MAX_PIXELS, MAX_SIDE

    c = RawClient(server.port)
    try:
        c.load()
        for w, h in (("inf", "120"), ("-640", "480"), ("nan", "1e12"), ("abc", "120")):  # kept: 160x120
            c.send("cam_config", img_w=w, img_h=h)
        c.drain()
        c.send("control", steering="0", throttle="0", brake="0")
        frame = Image.open(io.BytesIO(base64.b64decode(c.expect("telemetry")["image"])))
        assert frame.size == (160, 120)
        c.send("cam_config", img_w="5000", img_h="1000")  # 5 Mpx, 5000 px wide: over the limits
        c.drain()
        c.send("control", steering="0", throttle="0", brake="0")
        frame = Image.open(io.BytesIO(base64.b64decode(c.expect("telemetry", timeout=20)["image"])))
        w, h = frame.size
        assert w == MAX_SIDE and w * h <= MAX_PIXELS  # the side is the binding limit here
        assert w / h == pytest.approx(5.0, rel=0.01)
    finally:
        c.close()


def test_deeply_nested_json_ends_nothing_but_itself(server: DonkeyServer) -> None:
    c = RawClient(server.port)
    try:
        c.expect("scene_selection_ready")
        depth = 20000  # far beyond the interpreter's recursion limit, within the 64 KiB message limit
        c.sendraw(b'{"msg_type":"control","steering":' + b"[" * depth + b"]" * depth + b"}")
        c.send("get_protocol_version")
        assert c.expect("protocol_version")["version"] == "2"
    finally:
        c.close()


def test_stream_skips_nested_junk_and_reads_on() -> None:
    stream = proto.JsonStream()
    nested = b'{"a":' + b"[" * 100000 + b"]" * 100000 + b"}"
    assert stream.feed(nested + b'\n{"msg_type":"ok"}') == [{"msg_type": "ok"}]
    assert stream.errors == 1


def test_idle_and_oversized_clients_are_disconnected_and_free_their_slot() -> None:
    # idle: no scene asked for this long (scaled: a starved test thread must not look idle itself)
    with DonkeyServer(port=0, seeds=[5], max_clients=1, idle_timeout_s=scaled(0.5)) as srv:
        idle = RawClient(srv.port)
        idle.expect("scene_selection_ready")
        assert idle.closed_within(5.0)  # it never asked for a scene
        idle.close()
        big = RawClient(srv.port)  # the slot is free again
        big.expect("scene_selection_ready")
        big.sendraw(b'{"msg_type":"car_config","car_name":"' + b"x" * (100 * 1024) + b'"}')
        assert big.closed_within(5.0)
        big.close()
        ok = RawClient(srv.port)
        ok.expect("scene_selection_ready")
        ok.send("load_scene", scene_name="track_5")
        ok.expect("car_loaded")
        ok.expect("telemetry")
        ok.close()


def test_step_time_is_clamped_to_what_the_car_model_integrates(server: DonkeyServer) -> None:
    c = RawClient(server.port)
    try:
        c.load(synchronous=False)
        for asked, applied in (("1e6", 0.2), ("1e-9", 0.001), ("0.05", 0.05)):
            c.send("step_mode", step_mode="synchronous", time_step=asked)
            c.drain()
            c.send("control", steering="0", throttle="0.3", brake="0")
            first = c.expect("telemetry")["time"]
            c.send("control", steering="0", throttle="0.3", brake="0")
            assert c.expect("telemetry")["time"] - first == pytest.approx(applied, abs=1e-9)
    finally:
        c.close()


def test_silent_peers_do_not_lock_a_real_client_out(caplog: pytest.LogCaptureFixture, monkeypatch) -> None:
    """Issue 27 item 16: peers that connect and never send a message hold no slot a real client
    needs (the oldest silent one gives its slot up at once), and are dropped soon anyway; each
    drop says why, once."""
    from parts.bridges import donkey_server

    monkeypatch.setattr(donkey_server, "SILENT_EVICT_AGE_S", 0.0)  # not only peers silent for a while
    caplog.set_level("INFO", logger="parts.bridges")
    with DonkeyServer(port=0, seeds=[5], max_clients=4, hello_timeout_s=60) as srv:
        silent = [socket.create_connection(("127.0.0.1", srv.port), timeout=5) for _ in range(4)]
        try:
            ok = RawClient(srv.port)  # a real client, at once: not refused
            ok.expect("scene_selection_ready")
            ok.send("load_scene", scene_name="track_5")
            ok.expect("car_loaded")
            ok.close()
        finally:
            for s in silent:
                s.close()
    drops = [r.getMessage() for r in caplog.records if "sent no message" in r.getMessage()]
    assert 1 <= len(drops) <= 4 and "slot" in drops[0], drops


def test_silent_peers_are_dropped_after_the_hello_timeout() -> None:
    with DonkeyServer(port=0, seeds=[5], hello_timeout_s=0.3, idle_timeout_s=60) as srv:
        c = RawClient(srv.port)
        c.expect("scene_selection_ready")
        assert c.closed_within(5.0)  # it never said anything: no 60 s wait
        c.close()


def test_non_json_bytes_end_the_session_with_one_line(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level("DEBUG", logger="parts.bridges")
    with DonkeyServer(port=0, seeds=[5]) as srv:
        c = RawClient(srv.port)
        c.expect("scene_selection_ready")
        c.send("get_protocol_version")
        c.expect("protocol_version")
        with contextlib.suppress(OSError):
            for _ in range(200):  # 12.8 MB of text that holds no message
                c.sendraw(b"x" * 64 * 1024)
        assert c.closed_within(5.0)
        c.close()
    junk = [r for r in caplog.records if "not Donkey" in r.getMessage()]
    assert len(junk) == 1 and junk[0].levelname in ("WARNING", "ERROR"), [r.getMessage() for r in caplog.records]


def test_stream_counts_junk_outside_messages() -> None:
    stream = proto.JsonStream()
    assert stream.feed(b'  \n{"msg_type":"a"}\n\r\t  xyz{"msg_type":"b"}') == [{"msg_type": "a"}, {"msg_type": "b"}]
    assert stream.junk_bytes == 3
