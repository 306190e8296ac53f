"""Path follow in the built-in simulator: an expert lap recorded from the simulated sensors and
followed for 3 laps with odometry, GPS and both fused; a lost fix stops the car; the
path_follow template and `vehicle sim eval --path`."""

from __future__ import annotations

import importlib.util
import logging
import math

from parts.path.localizer import Localizer
from parts.sim.simulator import SimCar
from vehicle import Vehicle
from vehicle.app.assembly.drive import add_drive_mode
from vehicle.app.assembly.sim import add_sim_sensors
from vehicle.app.commands.createcar import create_car
from vehicle.app.evaluate import Engaged, evaluate
from vehicle.app.path_sim import PathDriver, _StaticPath, record_path, sensor_config
from vehicle.clock import SimulatedClock
from vehicle.config import Config
from vehicle.part_check import check_part

SEED = 1  # an 8 m track, road 0.8 m wide: off the road beyond 0.4 m from the centre line


def follow(localizer: str, laps: int = 3, **settings):
    cfg = Config.defaults(**settings)
    path = record_path(cfg, SEED, localizer)
    report = evaluate(PathDriver(path, localizer, cfg), [SEED], laps, cfg=cfg)
    return path, report["overall"]


def test_odometry_alone_follows_a_recorded_lap_three_times_on_the_road():
    path, o = follow("odometry")
    assert path.is_closed(1.0) and len(path) > 50
    print(f"odometry: mean distance to the recorded path {o['mean_path_distance']:.3f} m, "
          f"max {o['max_path_distance']:.3f} m, mean |cte| to the lane {o['mean_abs_cte']:.3f} m")
    assert o["laps_completed"] == 3 and o["interventions"] == 0 and o["autonomy"] == 100.0
    assert o["mean_path_distance"] < 0.05
    assert o["max_abs_cte"] < 0.2  # half the road's half width


def test_gps_alone_with_the_simulated_noise_of_an_rtk_receiver():
    # SIM_GPS_NOISE 5 cm, wandering over 10 s, 5 fixes per second: an RTK receiver; a consumer
    # receiver's metre leaves this 0.8 m road (docs/path_follow.md has its figures)
    path, o = follow("gps", SIM_GPS_NOISE=0.05)
    print(f"gps: mean distance to the recorded path {o['mean_path_distance']:.3f} m")
    assert o["laps_completed"] == 3 and o["interventions"] == 0
    assert o["mean_path_distance"] < 0.1


def test_fused_with_a_consumer_gps_stays_on_the_road():
    # SIM_GPS_NOISE 1 m: the fused filter follows odometry and takes the GPS's slow wander as its own;
    # the simulator's defaults (its LOC_ODOM_DRIFT, path_sim.SIM_ODOM_DRIFT), as `vehicle sim eval` uses
    path, o = follow("fused")
    print(f"fused: mean distance to the recorded path {o['mean_path_distance']:.3f} m")
    assert o["laps_completed"] == 3 and o["interventions"] == 0
    assert o["mean_path_distance"] < 0.1


class _FixLostAfter:
    """Part: the GPS receiver loses its fix after ``loops`` loops (a tunnel, a tree)."""

    INPUTS = ("gps/x", "gps/y", "gps/ok")
    OUTPUTS = ("gps/x", "gps/y", "gps/ok")

    def __init__(self, loops: int) -> None:
        self.loops = loops

    def run(self, x, y, ok):
        self.loops -= 1
        return (x, y, ok) if self.loops > 0 else (None, None, False)


def test_a_lost_fix_stops_the_car():
    cfg = sensor_config(Config.defaults(SIM_GPS_NOISE=0.05), "gps")
    path = record_path(cfg, SEED, "gps")
    sim = SimCar.from_config(cfg, seeds=[SEED], realtime=False, render=False)
    V = Vehicle(clock=SimulatedClock())
    V.add(sim)
    add_sim_sensors(V, cfg, sim)
    V.add(_FixLostAfter(100))  # 5 s at 20 Hz, the car at speed
    V.add(Localizer.from_config(cfg, "gps"))
    V.add(_StaticPath(path))
    V.add(Engaged())
    driver = PathDriver(path, "gps", cfg)
    V.add(driver.follower, outputs=list(driver.follower.OUTPUTS))
    add_drive_mode(V, cfg)
    seen = []
    V.add(lambda *v: seen.append(v), inputs=["path/state", "throttle", "loc/ok", "sim/speed"], outputs=[])
    V.start(rate_hz=20, max_loop_count=160, log_summary=False)
    assert seen[90][0] == "following" and seen[90][3] > 1.0
    assert all(s[0] == "lost" and s[1] == 0.0 and s[2] is False for s in seen[100:])
    assert seen[-1][3] < 0.05  # stopped: no throttle while the pose is not trustworthy


def _path_car(tmp_path, settings: str):
    car = tmp_path / "car"
    result = create_car(car, "path_follow")
    assert sorted(result.written) == ["manage.py", "myconfig.py"]
    (car / "myconfig.py").write_text((car / "myconfig.py").read_text() + settings)
    spec = importlib.util.spec_from_file_location("path_follow_manage", car / "manage.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return car, module


def test_template_records_an_expert_lap_and_follows_it_in_the_simulator(tmp_path, caplog):
    car, manage = _path_car(tmp_path, "WEB_CONTROL_PORT = 0\nSIM_REALTIME = False\n")
    assert manage.main(["expert-path", "--track", "1"]) == 0
    assert (car / "donkey_path.csv").read_text().startswith("x,y,speed\n0.0000,0.0000,")
    with caplog.at_level(logging.INFO):
        assert manage.main(["drive", "--sim", "--mode", "local", "--max-loops", "400"]) == 0
    assert "path: loaded" in caplog.text
    assert "1 laps on track 1, 0 resets" in caplog.text  # 20 s: a lap driven by the follower, on the road


def test_template_parts_keep_the_part_contract(tmp_path):
    from vehicle.app import assembly

    car, _ = _path_car(tmp_path, "")
    cfg = sensor_config(Config.defaults(CAR_PATH=str(car), WEB_CONTROL_PORT=0), "fused")
    V = Vehicle(clock=SimulatedClock())
    sim = SimCar.from_config(cfg, realtime=False, render=False, measured_speed=False)
    V.add(sim)
    add_sim_sensors(V, cfg, sim)
    V.add(Engaged())
    assembly.add_path_follow(V, cfg, "fused")
    from parts.path.buttons import PathCommands
    from parts.path.follower import PathFollower
    from parts.path.recorder import PathRecorder

    for cls in (PathCommands, Localizer, PathRecorder, PathFollower):
        (part,) = V.find(cls)
        check_part(part)


def test_path_localizer_without_its_sensor_is_a_one_line_error(tmp_path, capsys):
    _, manage = _path_car(tmp_path, 'PATH_LOCALIZER = "gps"\nDRIVE_TRAIN_TYPE = "MOCK"\nWEB_CONTROL_PORT = 0\n')
    assert manage.main(["drive", "--max-loops", "5"]) == 2
    err = capsys.readouterr().err
    assert "PATH_LOCALIZER = 'gps' needs a GPS: HAVE_GPS = True" in err and "Traceback" not in err


def test_sim_eval_compares_a_path_and_a_pilot_in_one_table(tmp_path, capsys):
    from vehicle.app.cli import main

    out = tmp_path / "lap.csv"
    assert main(["sim", "record-path", "--track", "1", "--out", str(out)]) == 0
    assert main(["sim", "eval", "--pilot", "expert", "--path", str(out), "--tracks", "1", "--laps", "1"]) == 0
    text = capsys.readouterr().out
    table = text[text.index("driver"):].splitlines()
    assert "path|d| m" in table[0]
    assert table[2].split()[0] == "expert" and table[2].split()[-1] == "-"
    assert table[3].startswith("path lap.csv (odometry)") and float(table[3].split()[-1]) < 0.05
    assert main(["sim", "eval", "--path", str(out), "--tracks", "1,2"]) == 2
    assert "a path belongs to the track it was recorded on" in capsys.readouterr().err


def test_path_geometry_of_the_simulator_frames():
    # the GPS frame with a fixed origin is the track's frame; odometry's is the start pose
    cfg = sensor_config(Config.defaults(SIM_GPS_NOISE=0.0), "gps")
    assert cfg.GPS_ORIGIN is not None and cfg.HAVE_GPS and not cfg.HAVE_ODOM
    path = record_path(cfg, SEED, "gps")
    sim = SimCar.from_config(cfg, seeds=[SEED], realtime=False, render=False)
    start = sim.car.state
    assert math.hypot(path.xy[0][0] - start.x, path.xy[0][1] - start.y) < 0.05


class _Script:
    """Part: the driver page's path buttons at given loops (``web/path_command``)."""

    OUTPUTS = ("web/path_command",)

    def __init__(self, at: dict[int, str]) -> None:
        self.at, self.loop = at, 0

    def run(self):
        self.loop += 1
        return self.at.get(self.loop)


def test_real_car_records_a_path_from_its_encoder_and_saves_it(tmp_path):
    # the template's drive() on the car: sensors from the sensor tables (an Arduino encoder on a
    # pty, written from DonkeyCar's sketch protocol), the page, the path parts, a MOCK drivetrain
    import sys
    from pathlib import Path

    from vehicle.app import assembly

    sys.path.insert(0, str(Path(__file__).parents[2] / "parts" / "sensors"))
    from sensor_fakes import ArduinoEncoder

    encoder = ArduinoEncoder()
    try:
        cfg = Config.defaults(CAR_PATH=str(tmp_path), HAVE_ODOM=True, ENCODER_TYPE="arduino",
                              ODOM_SERIAL=encoder.path, MM_PER_TICK=10.0, DRIVE_TRAIN_TYPE="MOCK",
                              WEB_CONTROL_PORT=0, PATH_MIN_DIST=0.1)
        V = Vehicle()
        assembly.add_sensors(V, cfg)
        assembly.add_controller(V, cfg)
        # after the page's controller, which writes web/path_command too (None: no button pressed)
        V.add(_Script({5: "record", 120: "record", 121: "save"}))
        assembly.add_path_follow(V, cfg)
        assembly.add_drive_mode(V, cfg)
        assembly.add_drivetrain(V, cfg)
        encoder.step = 3  # the wheel turns: 3 ticks of 10 mm per 20 ms
        states = []
        V.add(lambda s: states.append(s), inputs=["path/state"], outputs=[])
        V.start(rate_hz=50, max_loop_count=130)
    finally:
        encoder.close()
    from parts.path.pathfile import load_path

    path = load_path(tmp_path / "donkey_path.csv")
    assert "recording" in states and states[-1] == "ready"
    assert len(path) >= 3 and path.xy[-1][0] > 0.2 and abs(float(path.xy[-1][1])) < 1e-3  # straight ahead


def test_the_path_driver_reads_what_its_follower_reads():
    from parts.path.follower import PathFollower
    from vehicle.app.path_sim import PathDriver

    assert PathDriver.INPUTS == PathFollower.INPUTS
    assert PathDriver.OPTIONAL_INPUTS == PathFollower.OPTIONAL_INPUTS


def test_the_simulated_car_has_its_own_odometry_drift_unless_the_user_sets_one():
    from vehicle.app.path_sim import SIM_ODOM_DRIFT, sensor_config

    assert Config.defaults().LOC_ODOM_DRIFT == 0.02
    assert sensor_config(Config.defaults(), "fused").LOC_ODOM_DRIFT == SIM_ODOM_DRIFT == 0.005
    assert sensor_config(Config.defaults(LOC_ODOM_DRIFT=0.03), "fused").LOC_ODOM_DRIFT == 0.03
