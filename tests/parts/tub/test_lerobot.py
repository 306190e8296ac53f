"""LeRobot v3.0 export and import: every file read back with pyarrow and PyAV and checked against the
schema; round trips tub -> LeRobot -> tub; datasets written by LeRobot itself imported."""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fixtures.tubs import gradient_image

from parts.tub.errors import TubError
from parts.tub.lerobot import export_lerobot, import_lerobot
from parts.tub.lerobot.format import LeRobotFormatError
from parts.tub.lerobot.stats import ImageStats, RunningStats
from parts.tub.reader import load_records
from parts.tub.tub import Tub

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")
av = pytest.importorskip("av")

FIXTURES = Path(__file__).parent / "fixtures"
H, W = 48, 64
T0 = 1_700_000_000_000
LABELS = ["Left_Lane", "Right_Lane"]
DELETED = [45, 46, 47]
FLOAT32_FIELDS = {"user/angle", "user/throttle", "enc/speed", "behavior/one_hot_state_array"}
INPUTS = ["cam/image_array", "user/angle", "user/throttle", "user/mode", "enc/speed", "behavior/state",
          "behavior/label", "behavior/one_hot_state_array", "pilot/angle", "sim/track", "sim/pos", "flag"]
TYPES = ["image_array", "float", "float", "str", "float", "int", "str", "list", "float", "int", "list",
         "boolean"]
# Video: AV1 yuv420p at crf 30 on top of the tub's JPEG. On these 64x48 test frames (gradients with
# pixel noise of +-15, which a video codec smooths away) the worst frame measured 27.6 dB PSNR after
# export and a mean |error| of 6.0 levels of 255 after the round trip (video, then JPEG q95 in the
# tub). On the simulator's camera frames: >= 32 dB, <= 3.9 levels (docs/data-format.md).
VIDEO_MEAN_ABS = 8.0
VIDEO_PSNR_DB = 26.0


def frame(i: int) -> np.ndarray:
    return gradient_image(i % 40, H, W)


def rich_tub(path: Path) -> list[tuple[int, dict[str, Any]]]:
    """Two recording sessions: the first changes simulator track half way, the second has a 3 s
    pause after 10 records and 3 records deleted 5 records later (a 200 ms gap). Returns the
    (timestamp, values) of the live records as written."""
    written = []
    t = T0
    n = 0
    for session, count in ((0, 30), (1, 25)):
        with Tub(path, INPUTS, TYPES, {"driver": "ann"}, fsync=False) as tub:
            for i in range(count):
                t += 50 + (n % 3)  # a 20 Hz loop with jitter
                if session == 1 and i == 10:
                    t += 3000
                state = (n // 10) % 2
                rec = {"cam/image_array": frame(n), "user/angle": round(math.sin(n / 7), 4),
                       "user/throttle": 0.2 + n / 1000, "user/mode": "user" if n % 5 else "local_angle",
                       "enc/speed": 1.0 + n / 50, "behavior/state": state, "behavior/label": LABELS[state],
                       "behavior/one_hot_state_array": [1.0 - state, float(state)],
                       "pilot/angle": -0.25 if n % 5 == 0 else None,
                       "sim/track": 1 if session == 1 or i < 15 else 2, "sim/pos": [n * 0.5, -n * 0.25],
                       "flag": n % 2 == 0}
                tub.write_record(rec, timestamp_ms=t)
                written.append((t, {k: v for k, v in rec.items() if v is not None}))
                n += 1
        if session == 1:
            with Tub(path) as tub:
                tub.delete_records(DELETED)
    return [w for i, w in enumerate(written) if i not in DELETED]


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> tuple[Path, list[tuple[int, dict[str, Any]]]]:
    path = tmp_path_factory.mktemp("src") / "tub"
    return path, rich_tub(path)


@pytest.fixture(scope="module")
def exported(source, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ds") / "video"
    export_lerobot([source[0]], out)
    return out



@pytest.mark.skipif(not hasattr(os, "sched_getscheduler"), reason="POSIX scheduling policies")
def test_encoding_leaves_the_threads_scheduling_alone(source, tmp_path):
    # SVT-AV1 (LeRobot's codec), run as root, set the exporting thread to SCHED_FIFO 99 and left it
    # so: every process started afterwards was real-time, and a busy one starved the test process
    before = os.sched_getscheduler(0), os.sched_getparam(0)
    export_lerobot([source[0]], tmp_path / "ds", codec="libsvtav1")
    assert (os.sched_getscheduler(0), os.sched_getparam(0)) == before

# -- reading a dataset back with pyarrow and PyAV, checking it against its own schema -------------------

def arrow_type_ok(field: Any, ft: dict[str, Any]) -> bool:
    dtypes = {"float32": pa.float32(), "float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_(),
              "string": pa.string()}
    if ft["dtype"] == "image":
        return field.type == pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    if ft["shape"] == [1]:
        return field.type == dtypes[ft["dtype"]]
    return pa.types.is_fixed_size_list(field.type) and field.type.list_size == ft["shape"][0] \
        and field.type.value_type == dtypes[ft["dtype"]]


def chunk_file(path: Path) -> tuple[int, int]:
    """``.../chunk-001/file-002.parquet`` -> (1, 2)."""
    return int(path.parent.name.split("-")[1]), int(path.stem.split("-")[1])


def read_dataset(root: Path) -> dict[str, Any]:
    """Every file of a v3.0 dataset, checked against info.json on the way (across file rollovers:
    each episode's rows, episode row and frames are in the files its indexes name)."""
    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["splits"] == {"train": f"0:{info['total_episodes']}"}
    chunks_size = info["chunks_size"]
    features = info["features"]
    for name, default in (("timestamp", "float32"), ("frame_index", "int64"), ("episode_index", "int64"),
                          ("index", "int64"), ("task_index", "int64")):
        assert features[name] == {"dtype": default, "shape": [1], "names": None}
    assert "/" not in "".join(features)  # LeRobot forbids "/" in feature names
    videos = [k for k, f in features.items() if f["dtype"] == "video"]
    assert (info["video_path"] is not None) == bool(videos)
    if videos:
        assert info["video_path"] == "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"

    data_files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    assert all(chunk_file(p)[1] < chunks_size for p in data_files)
    tables = [pq.read_table(p) for p in data_files]
    data = pa.concat_tables(tables)
    row_file = [chunk_file(p) for p, t in zip(data_files, tables, strict=True) for _ in range(t.num_rows)]
    columns = [k for k, f in features.items() if f["dtype"] != "video"]
    assert data.column_names == columns
    hf = json.loads(tables[0].schema.metadata[b"huggingface"])["info"]["features"]
    assert list(hf) == columns
    for name in columns:
        ft = features[name]
        assert arrow_type_ok(data.schema.field(name), ft), (name, data.schema.field(name).type, ft)
        expected_hf = {"_type": "Image"} if ft["dtype"] == "image" else \
            {"dtype": ft["dtype"], "_type": "Value"} if ft["shape"] == [1] else \
            {"feature": {"dtype": ft["dtype"], "_type": "Value"}, "length": ft["shape"][0], "_type": "List"}
        assert hf[name] == expected_hf
    rows = data.to_pylist()
    assert len(rows) == info["total_frames"]
    assert [r["index"] for r in rows] == list(range(len(rows)))

    tasks_table = pq.read_table(root / "meta/tasks.parquet")
    pandas_meta = json.loads(tasks_table.schema.metadata[b"pandas"])
    text_col = pandas_meta["index_columns"][0]
    tasks = dict(zip(tasks_table.column("task_index").to_pylist(), tasks_table.column(text_col).to_pylist(),
                     strict=True))
    assert sorted(tasks) == list(range(info["total_tasks"]))

    episodes = []
    for path in sorted((root / "meta/episodes").glob("chunk-*/file-*.parquet")):
        for ep in pq.read_table(path).to_pylist():  # each episode row says which file holds it
            assert (ep["meta/episodes/chunk_index"], ep["meta/episodes/file_index"]) == chunk_file(path)
            episodes.append(ep)
    assert [e["episode_index"] for e in episodes] == list(range(info["total_episodes"]))
    fps = info["fps"]
    decoded: dict[str, dict[tuple[int, int], list[tuple[float, np.ndarray]]]] = {}
    for key in videos:
        vinfo = features[key]["info"]
        assert vinfo["video.codec"] == "av1" and vinfo["video.pix_fmt"] == "yuv420p"
        assert vinfo["video.fps"] == fps and vinfo["has_audio"] is False
        assert [vinfo["video.height"], vinfo["video.width"], vinfo["video.channels"]] == features[key]["shape"]
        decoded[key] = {}
        for path in sorted((root / "videos" / key).glob("chunk-*/file-*.mp4")):
            with av.open(str(path)) as container:
                stream = container.streams.video[0]
                assert stream.codec_context.name in ("libdav1d", "av1") and stream.pix_fmt == "yuv420p"
                decoded[key][chunk_file(path)] = [(float(f.time), f.to_ndarray(format="rgb24"))
                                                  for f in container.decode(stream)]
        assert sum(map(len, decoded[key].values())) == info["total_frames"]
    end = 0
    video_end: dict[tuple[str, int, int], float] = {}
    frames: dict[str, list[tuple[float, np.ndarray]]] = {key: [] for key in videos}
    for ep in episodes:
        mine = [r for r in rows if r["episode_index"] == ep["episode_index"]]
        assert ep["dataset_from_index"] == end == mine[0]["index"]
        assert ep["dataset_to_index"] == end + ep["length"] == mine[-1]["index"] + 1
        end = ep["dataset_to_index"]
        assert [r["frame_index"] for r in mine] == list(range(ep["length"]))
        for r in mine:  # LeRobot finds a video frame at from_timestamp + timestamp, frame_index / fps
            assert r["timestamp"] == pytest.approx(r["frame_index"] / fps, abs=1e-6)
            assert row_file[r["index"]] == (ep["data/chunk_index"], ep["data/file_index"])
        assert set(ep["tasks"]) == {tasks[r["task_index"]] for r in mine}
        for key in videos:
            where = (key, ep[f"videos/{key}/chunk_index"], ep[f"videos/{key}/file_index"])
            assert where[2] < chunks_size
            # episodes follow each other in a file, the first at 0
            assert ep[f"videos/{key}/from_timestamp"] == pytest.approx(video_end.get(where, 0.0))
            assert ep[f"videos/{key}/to_timestamp"] == pytest.approx(ep[f"videos/{key}/from_timestamp"]
                                                                     + ep["length"] / fps)
            video_end[where] = ep[f"videos/{key}/to_timestamp"]
            in_file = decoded[key][where[1:]]
            for r in mine:  # the frame LeRobot would look up for each row, within its 1e-4 s tolerance
                t = ep[f"videos/{key}/from_timestamp"] + r["timestamp"]
                found = in_file[int(round(t * fps))]
                assert abs(found[0] - t) < 1e-4
                frames[key].append(found)
        for name, ft in features.items():
            if ft["dtype"] == "string":
                assert f"stats/{name}/mean" not in ep
                continue
            shape = (ft["shape"][2], 1, 1) if ft["dtype"] in ("video", "image") else (ft["shape"][0],)
            for stat in ("min", "max", "mean", "std", "q01", "q10", "q50", "q90", "q99"):
                assert np.asarray(ep[f"stats/{name}/{stat}"]).shape == shape, (name, stat)
            if ft["dtype"] not in ("video", "image"):
                check_stats(ep, f"stats/{name}/", column(mine, name, ft))
    for key in videos:  # every frame of every file belongs to exactly one row
        assert len(frames[key]) == info["total_frames"]
        assert {id(f[1]) for f in frames[key]} == {id(f[1]) for fs in decoded[key].values() for f in fs}
    stats = json.loads((root / "meta/stats.json").read_text())
    assert set(stats) == {k for k, f in features.items() if f["dtype"] != "string"}
    for name, ft in features.items():
        if ft["dtype"] not in ("video", "image", "string"):
            check_stats({f"{name}/{k}": v for k, v in stats[name].items()}, f"{name}/", column(rows, name, ft))
    return {"info": info, "rows": rows, "episodes": episodes, "tasks": tasks, "stats": stats, "frames": frames}


def column(rows: list[dict[str, Any]], name: str, ft: dict[str, Any]) -> np.ndarray:
    values = np.asarray([r[name] for r in rows], dtype=np.float64)
    return values.reshape(len(rows), int(ft["shape"][0]))


def check_stats(stats: dict[str, Any], prefix: str, values: np.ndarray) -> None:
    """LeRobot's statistics (population std) of the values, NaN rows left out."""
    values = values[~np.isnan(values).any(axis=1)]
    assert stats[prefix + "count"] == [len(values)]
    np.testing.assert_allclose(stats[prefix + "min"], values.min(axis=0))
    np.testing.assert_allclose(stats[prefix + "max"], values.max(axis=0))
    np.testing.assert_allclose(stats[prefix + "mean"], values.mean(axis=0), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(stats[prefix + "std"], values.std(axis=0), rtol=1e-7, atol=1e-9)
    for q in (1, 10, 50, 90, 99):
        assert_quantile(np.asarray(stats[prefix + f"q{q:02d}"]), values, q / 100)


def assert_quantile(estimate: np.ndarray, values: np.ndarray, q: float) -> None:
    """A histogram quantile (LeRobot's method) lies between the samples around rank q*n, give or
    take a few of its 5000 bins (the bins move when the range grows)."""
    if len(values) < 2:
        np.testing.assert_allclose(estimate, values.mean(axis=0))  # LeRobot: the mean
        return
    ordered = np.sort(values, axis=0)
    n = len(values)
    lo = ordered[max(0, int(np.floor(q * n)) - 2)]
    hi = ordered[min(n - 1, int(np.ceil(q * n)) + 1)]
    slack = (ordered[-1] - ordered[0]) * 5 / 5000 + 1e-9
    assert np.all((estimate >= lo - slack) & (estimate <= hi + slack)), (q, estimate, lo, hi)


# -- export ---------------------------------------------------------------------------------------------

def test_export_matches_the_v3_schema_field_by_field(source, exported):
    tub, written = source
    ds = read_dataset(exported)
    info, rows, episodes = ds["info"], ds["rows"], ds["episodes"]
    features = info["features"]
    assert info["fps"] == 20 and info["total_frames"] == len(written) == 52
    assert (info["chunks_size"], info["data_files_size_in_mb"], info["video_files_size_in_mb"]) == (1000, 100, 200)
    assert {(e["data/chunk_index"], e["data/file_index"]) for e in episodes} == {(0, 0)}
    # episodes: session 0 track 1, session 0 track 2, session 1 before and after the 3 s pause
    assert [e["length"] for e in episodes] == [15, 15, 10, 12]
    assert info["total_episodes"] == 4 and info["robot_type"] == "donkeycar"
    assert features["observation.images.cam"]["shape"] == [H, W, 3]
    assert features["observation.images.cam"]["dtype"] == "video"
    assert features["observation.state"] == {"dtype": "float32", "shape": [3],
                                             "names": ["speed", "behavior.Left_Lane", "behavior.Right_Lane"]}
    assert features["action"] == {"dtype": "float32", "shape": [2], "names": ["angle", "throttle"]}
    assert features["user.mode"]["dtype"] == "string" and features["sim.track"]["dtype"] == "int64"
    assert features["pilot.angle"]["dtype"] == "float64" and features["flag"]["dtype"] == "bool"
    assert features["sim.pos"] == {"dtype": "float64", "shape": [2], "names": None}
    assert ds["tasks"] == {0: "Left_Lane", 1: "Right_Lane"}
    for row, (ts, rec) in zip(rows, written, strict=True):
        assert row["action"] == pytest.approx([rec["user/angle"], rec["user/throttle"]], rel=1e-6)
        assert row["observation.state"] == pytest.approx([rec["enc/speed"], *rec["behavior/one_hot_state_array"]],
                                                         rel=1e-6)
        assert ds["tasks"][row["task_index"]] == rec["behavior/label"]
        assert row["user.mode"] == rec["user/mode"] and row["sim.track"] == rec["sim/track"]
        assert row["sim.pos"] == rec["sim/pos"] and row["flag"] == rec["flag"]
        if "pilot/angle" in rec:
            assert row["pilot.angle"] == rec["pilot/angle"]
        else:  # missing in the tub: NaN
            assert math.isnan(row["pilot.angle"])
        ep = episodes[row["episode_index"]]
        assert ep["tub/capture_start_ms"] + round(row["capture_timestamp"] * 1000) == ts
    assert [e["tub/session_id"].rsplit("_", 1)[1] for e in episodes] == ["0", "0", "1", "1"]
    assert [e["tub/index"] for e in episodes] == [0, 0, 0, 0] and {e["tub/name"] for e in episodes} == {"tub"}
    assert (episodes[3]["tub/first_index"], episodes[3]["tub/last_index"]) == (40, 54)
    # image statistics: per channel, in [0, 1], from every source frame
    src = np.stack([r.image() for r in load_records(tub)]).astype(np.float64) / 255
    img = ds["stats"]["observation.images.cam"]
    assert np.asarray(img["mean"]).shape == (3, 1, 1) and img["count"] == [52]
    np.testing.assert_allclose(np.asarray(img["mean"]).ravel(), src.mean(axis=(0, 1, 2)), atol=1e-9)
    np.testing.assert_allclose(np.asarray(img["std"]).ravel(), src.std(axis=(0, 1, 2)), atol=1e-9)
    np.testing.assert_allclose(np.asarray(img["q50"]).ravel(), np.quantile(src, 0.5, axis=(0, 1, 2),
                                                                           method="inverted_cdf"), atol=1e-9)
    # ... and per episode, from the episode's frames
    for ep in episodes:
        mine = src[ep["dataset_from_index"]:ep["dataset_to_index"]]
        assert ep["stats/observation.images.cam/count"] == [ep["length"]]
        for stat, value in (("mean", mine.mean(axis=(0, 1, 2))), ("std", mine.std(axis=(0, 1, 2))),
                            ("min", mine.min(axis=(0, 1, 2))), ("max", mine.max(axis=(0, 1, 2))),
                            ("q10", np.quantile(mine, 0.1, axis=(0, 1, 2), method="inverted_cdf")),
                            ("q99", np.quantile(mine, 0.99, axis=(0, 1, 2), method="inverted_cdf"))):
            np.testing.assert_allclose(np.asarray(ep[f"stats/observation.images.cam/{stat}"]).ravel(), value,
                                       atol=1e-9, err_msg=f"episode {ep['episode_index']} {stat}")
    # the video holds the frames, within the codec's loss
    for (_, got), rec in zip(ds["frames"]["observation.images.cam"], load_records(tub), strict=True):
        assert psnr(rec.image(), got) >= VIDEO_PSNR_DB
    sidecar = json.loads((exported / "meta/vehicle_rc.json").read_text())
    assert sidecar["tubs"][0]["inputs"] == INPUTS and sidecar["task"]["key"] == "behavior/label"


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return 99.0 if mse == 0 else 10 * math.log10(255 ** 2 / mse)


def test_images_mode_keeps_the_tubs_jpeg_bytes(source, tmp_path):
    tub, _ = source
    out = tmp_path / "img"
    report = export_lerobot(tub, out, video=False, fps=25)
    assert report.fps == 25 and not report.fps_measured
    ds = read_dataset(out)
    assert ds["info"]["features"]["observation.images.cam"]["dtype"] == "image"
    assert ds["info"]["video_path"] is None and not (out / "videos").exists()
    for row, rec in zip(ds["rows"], load_records(tub), strict=True):
        assert row["observation.images.cam"]["bytes"] == rec.image_bytes()
        assert row["observation.images.cam"]["path"] == f"frame-{row['frame_index']:06d}.jpg"
        assert row["timestamp"] == pytest.approx(row["frame_index"] / 25)


def test_max_gap_and_sessions_decide_the_episodes(source, tmp_path):
    tub, _ = source
    report = export_lerobot(tub, tmp_path / "a", max_gap_s=None, video=False)
    assert report.episodes == 3  # the pause no longer splits
    report = export_lerobot(tub, tmp_path / "b", max_gap_s=0.1, video=False)
    assert report.episodes == 5  # now the gap of the 3 deleted records splits too


# -- round trips -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("video", [True, False])
def test_round_trip_keeps_every_value(source, exported, tmp_path, video):
    tub, written = source
    ds = exported if video else tmp_path / "img"
    if not video:
        export_lerobot(tub, ds, video=False)
    report = import_lerobot(ds, tmp_path / "back")
    assert report.exact and report.records == len(written) and report.episodes == 4
    back = Tub(tmp_path / "back", read_only=True)
    assert back.inputs == INPUTS and back.types == TYPES and back.metadata["driver"] == "ann"
    originals = load_records(tub)
    for rec, (ts, values), src in zip(load_records(tmp_path / "back"), written, originals, strict=True):
        assert rec.timestamp_ms == ts
        got = {k: v for k, v in rec.data.items() if not k.startswith("_") and k != "cam/image_array"}
        want = {k: v for k, v in values.items() if k != "cam/image_array"}
        assert got.keys() == want.keys()
        for key in want:
            if key in FLOAT32_FIELDS:  # LeRobot's action and state are float32: 2**-24 relative rounding
                assert got[key] == pytest.approx(want[key], rel=2 ** -24, abs=1e-30)
                assert type(got[key]) is type(want[key])
            else:  # everything else exactly, types included
                assert got[key] == want[key] and type(got[key]) is type(want[key]), key
        if video:
            assert np.mean(np.abs(rec.image().astype(int) - src.image().astype(int))) <= VIDEO_MEAN_ABS
        else:
            assert rec.image_bytes() == src.image_bytes()


def test_import_datasets_written_by_lerobot(tmp_path):
    """Fixtures written by lerobot 0.4.4's own LeRobotDataset (fixtures/make_lerobot_fixture.py)."""
    for kind in ("video", "images"):
        report = import_lerobot(FIXTURES / f"lerobot_v30_{kind}", tmp_path / kind)
        assert not report.exact and report.records == 11 and report.episodes == 2
        recs = load_records(tmp_path / kind)
        tub = Tub(tmp_path / kind, read_only=True)
        assert tub.inputs == ["cam/image_array", "observation/state", "user/angle", "user/throttle", "next/done",
                              "lerobot/task", "lerobot/episode_index"]
        assert tub.types == ["image_array", "vector", "float", "float", "boolean", "str", "int"]
        for rec, (ep, i) in zip(recs, [(0, i) for i in range(6)] + [(1, i) for i in range(5)], strict=True):
            assert rec.angle == pytest.approx(0.1 * i - 0.3, abs=1e-6) and rec.throttle == 0.2 + 0.05 * ep
            assert rec["observation/state"] == [0.5 * i, 0.1 * ep, -0.2]
            assert rec["next/done"] == (i == (5 if ep == 0 else 4))
            assert rec["lerobot/task"] == ("turn left", "turn right")[ep] and rec["lerobot/episode_index"] == ep
            yy, xx = np.mgrid[0:48, 0:64]
            expected = np.stack([(xx * 4 + i * 9) % 256, (yy * 5 + ep * 60) % 256, np.full_like(xx, 40 * i)], -1)
            # PNG in the data files (lossless) then our JPEG; AV1 video then our JPEG
            assert np.mean(np.abs(rec.image().astype(int) - expected)) <= (5.0 if kind == "images" else 12.0)
        # episodes follow each other 1 s apart at the dataset's 10 fps
        assert recs[1].timestamp_ms - recs[0].timestamp_ms == 100
        assert recs[6].timestamp_ms - recs[5].timestamp_ms == 1100


# -- statistics ----------------------------------------------------------------------------------------

def test_running_stats_match_numpy_across_batches_and_growing_ranges():
    rng = np.random.default_rng(3)
    data = np.concatenate([rng.normal(0, 1, (500, 3)), rng.normal(5, 3, (700, 3)), rng.uniform(-20, 40, (300, 3))])
    acc = RunningStats(3)
    for i in range(0, len(data), 128):  # each batch widens the range: the histogram is rebinned
        acc.update(data[i:i + 128])
    acc.update(np.full((4, 3), np.nan))  # missing values are left out
    out = acc.result()
    assert out["count"].tolist() == [len(data)]
    np.testing.assert_allclose(out["mean"], data.mean(axis=0))
    np.testing.assert_allclose(out["std"], data.std(axis=0))
    np.testing.assert_allclose(out["min"], data.min(axis=0))
    for q in (1, 10, 50, 90, 99):
        assert_quantile(out[f"q{q:02d}"], data, q / 100)
    one = RunningStats(2)
    one.update(np.array([[1.0, 2.0]]))
    assert one.result()["q50"].tolist() == [1.0, 2.0] and one.result()["std"].tolist() == [0.0, 0.0]


def test_image_stats_are_exact_per_channel():
    frames = [gradient_image(i, 30, 40) for i in range(7)]
    acc = ImageStats(3)
    for f in frames:
        acc.update(f)
    out = acc.result()
    px = np.stack(frames).reshape(-1, 3).astype(np.float64) / 255
    assert out["count"].tolist() == [7]
    for key, value in (("mean", px.mean(axis=0)), ("std", px.std(axis=0)), ("min", px.min(axis=0)),
                       ("max", px.max(axis=0)), ("q90", np.quantile(px, 0.9, axis=0, method="inverted_cdf"))):
        assert out[key].shape == (3, 1, 1)
        np.testing.assert_allclose(out[key].ravel(), value, atol=1e-12)


def synthetic_tub(path: Path, n: int) -> None:
    with Tub(path, ["cam/image_array", "user/angle", "user/throttle"], ["image_array", "float", "float"],
             fsync=False) as tub:
        img = gradient_image(0, H, W)
        for i in range(n):
            tub.write_record({"cam/image_array": img, "user/angle": math.sin(i), "user/throttle": 0.5},
                             timestamp_ms=T0 + 50 * i)


def test_export_memory_does_not_grow_with_the_records(tmp_path, monkeypatch):
    """Python-side peak memory (tracemalloc: numpy buffers included) of exporting 4x the records
    stays flat: rows are written in groups and statistics are accumulated, never the records kept.
    Groups of 250 rows here (2000 by default), so both runs fill several."""
    from parts.tub.lerobot import export as export_module

    monkeypatch.setattr(export_module, "ROWS_PER_GROUP", 250)
    peaks = []
    for n in (1000, 4000):
        synthetic_tub(tmp_path / f"t{n}", n)
        tracemalloc.start()
        export_lerobot(tmp_path / f"t{n}", tmp_path / f"d{n}", video=False)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        meta = pq.ParquetFile(next((tmp_path / f"d{n}" / "data").glob("*/*.parquet"))).metadata
        assert meta.num_rows == n and meta.num_row_groups == n // 250
    assert peaks[1] < peaks[0] * 1.25, peaks


# -- bad input -------------------------------------------------------------------------------------------

def test_bad_input_is_one_clear_error_and_nothing_is_lost(source, exported, tmp_path):
    tub, _ = source
    (tmp_path / "notatub").mkdir()
    with pytest.raises(TubError, match="holds no tub"):
        export_lerobot(tmp_path / "notatub", tmp_path / "x")
    assert not (tmp_path / "x").exists()
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("mine")
    with pytest.raises(TubError, match="exists and is not empty"):
        export_lerobot(tub, full)
    with pytest.raises(TubError, match="exists and is not empty"):
        import_lerobot(exported, full)
    assert [p.name for p in full.iterdir()] == ["keep.txt"]
    old = tmp_path / "v21"
    shutil.copytree(exported / "meta", old / "meta")
    info = json.loads((old / "meta/info.json").read_text())
    info["codebase_version"] = "v2.1"
    (old / "meta/info.json").write_text(json.dumps(info))
    with pytest.raises(LeRobotFormatError, match="codebase version 'v2.1'.*convert_dataset_v21_to_v30"):
        import_lerobot(old, tmp_path / "y")
    with pytest.raises(LeRobotFormatError, match="not a LeRobot dataset"):
        import_lerobot(tmp_path / "notatub", tmp_path / "y")
    assert not (tmp_path / "y").exists()
    assert not list(tmp_path.glob(".*partial*"))


def test_depth_frames_gray16_go_both_ways_exactly(tmp_path):
    """A gray16_array field (16-bit PNG): an image feature [H, W, 1] beside the video, stats of one
    channel scaled to [0, 1] by 65535, the same PNGs back."""
    depth = [(np.arange(H * W, dtype=np.uint16).reshape(H, W) * (i + 1)) % 60000 for i in range(4)]
    with Tub(tmp_path / "t", ["cam/image_array", "cam/depth_array", "user/angle", "user/throttle"],
             ["image_array", "gray16_array", "float", "float"], fsync=False) as tub:
        for i in range(4):
            tub.write_record({"cam/image_array": frame(i), "cam/depth_array": depth[i], "user/angle": 0.0,
                              "user/throttle": 0.5}, timestamp_ms=T0 + 50 * i)
    export_lerobot(tmp_path / "t", tmp_path / "ds")
    ds = read_dataset(tmp_path / "ds")
    ft = ds["info"]["features"]["observation.images.cam_depth_array"]
    assert ft == {"dtype": "image", "shape": [H, W, 1], "names": ["height", "width", "channels"]}
    stats = ds["stats"]["observation.images.cam_depth_array"]
    assert np.asarray(stats["max"]).tolist() == [[[np.stack(depth).max() / 65535]]]
    import_lerobot(tmp_path / "ds", tmp_path / "back")
    for rec, original in zip(load_records(tmp_path / "back"), load_records(tmp_path / "t"), strict=True):
        assert rec.image_bytes("cam/depth_array") == original.image_bytes("cam/depth_array")
    assert np.array_equal(load_records(tmp_path / "back")[2].image("cam/depth_array"), depth[2])


def test_frames_of_another_size_stop_the_export_and_leave_nothing(donkey_tub, tmp_path):
    a, _ = donkey_tub(3, name="a", image_size=(48, 64))
    donkey_tub(3, name="b", image_size=(60, 80))
    with pytest.raises(LeRobotFormatError, match="must all have one size"):
        export_lerobot(tmp_path, tmp_path.parent / f"{tmp_path.name}-ds")
    assert not (tmp_path.parent / f"{tmp_path.name}-ds").exists()
    assert not list(tmp_path.parent.glob(f".{tmp_path.name}-ds.partial*"))


def test_missing_pyarrow_says_how_to_install(source, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(LeRobotFormatError, match=r"pyarrow is not installed.*pip install 'vehicle-rc\[datasets\]'"):
        export_lerobot(source[0], tmp_path / "x")


# -- the loop rate ---------------------------------------------------------------------------------------

def loop_tub(path: Path, hz: int, n: int = 400) -> None:
    """A recording at ``hz`` as a real loop makes it: capture times in whole milliseconds, a few ms
    of jitter around the schedule (std 1.5 ms, at most 4) and now and then a missed loop (a frame
    one period late)."""
    rng = np.random.default_rng(hz)
    period = 1000.0 / hz
    t = 0.0
    with Tub(path, ["user/angle", "user/throttle"], ["float", "float"], fsync=False) as tub:
        for i in range(n):
            t += period * (2 if i % 41 == 40 else 1)
            jitter = float(np.clip(rng.normal(0.0, 1.5), -4.0, 4.0))
            tub.write_record({"user/angle": 0.0, "user/throttle": 0.3}, timestamp_ms=T0 + round(t + jitter))


@pytest.mark.parametrize("hz", [15, 20, 30, 50, 60])
def test_fps_is_measured_from_sub_millisecond_intervals(tmp_path, hz):
    """At 60 Hz the intervals are 16 or 17 whole ms: the median of those gave 59 (or 62) fps."""
    loop_tub(tmp_path / "t", hz)
    report = export_lerobot(tmp_path / "t", tmp_path / "ds", video=False)
    assert report.fps_measured and report.fps == hz
    assert json.loads((tmp_path / "ds/meta/info.json").read_text())["fps"] == hz


# -- the video encoder -----------------------------------------------------------------------------------

def test_an_encoder_failure_is_one_clear_error_and_leaves_nothing(donkey_tub, tmp_path, monkeypatch):
    odd, _ = donkey_tub(4, name="odd", image_size=(47, 63))
    out = tmp_path / "ds"
    for codec in ("h264", "hevc"):  # yuv420p: x264 and x265 refuse odd sizes (checked before encoding)
        with pytest.raises(LeRobotFormatError, match=rf"{codec}: .*63x47 .*even width and height.*libsvtav1"):
            export_lerobot(odd, out, codec=codec)
    assert export_lerobot(odd, tmp_path / "av1").frames == 4  # AV1 takes them
    # any failure of the encoder itself (here an option libx264 refuses) names codec and frame size
    from parts.tub.lerobot import video as video_module

    even, _ = donkey_tub(4, name="even", image_size=(48, 64))
    monkeypatch.setattr(video_module, "codec_options", lambda codec, crf: {"g": "2", "crf": "30", "preset": "warp9"})
    with pytest.raises(LeRobotFormatError, match=r"h264 .*64x48 frames.*\(--vcodec, --crf\)") as info:
        export_lerobot(even, out, codec="h264")
    assert "\n" not in str(info.value)
    assert not out.exists() and not list(tmp_path.glob(".ds.partial*"))


def test_crf_out_of_the_codecs_range_is_refused_up_front(donkey_tub, tmp_path):
    path, _ = donkey_tub(2, image_size=(48, 64))
    with pytest.raises(TubError, match=r"crf must be within 0\.\.51 for hevc, got 63"):
        export_lerobot(path, tmp_path / "ds", codec="hevc", crf=63)
    assert not (tmp_path / "ds").exists()


# -- malformed datasets ----------------------------------------------------------------------------------

EPISODES_FILE = "meta/episodes/chunk-000/file-000.parquet"
DATA_FILE = "data/chunk-000/file-000.parquet"


def _drop_column(ds: Path, file: str, name: str) -> None:
    pq.write_table(pq.read_table(ds / file).drop_columns([name]), ds / file)


def _null_column(ds: Path, file: str, name: str) -> None:
    table = pq.read_table(ds / file)
    i = table.column_names.index(name)
    table = table.set_column(i, name, pa.nulls(table.num_rows, table.schema.field(name).type))
    pq.write_table(table, ds / file)


def test_malformed_datasets_are_one_line_errors_naming_the_file(exported, tmp_path):
    cam = "videos/observation.images.cam"
    cases = [
        (lambda ds: _drop_column(ds, EPISODES_FILE, f"{cam}/from_timestamp"),
         rf"{EPISODES_FILE}: no column {cam}/from_timestamp"),
        (lambda ds: _null_column(ds, EPISODES_FILE, f"{cam}/file_index"),
         rf"{EPISODES_FILE}: episode 0 has no {cam}/file_index"),
        (lambda ds: _drop_column(ds, EPISODES_FILE, "episode_index"), rf"{EPISODES_FILE}: no column episode_index"),
        (lambda ds: (ds / "meta/vehicle_rc.json").write_text('{"format": 1, "tubs": ['),
         r"meta/vehicle_rc\.json is not valid JSON"),
        (lambda ds: _drop_column(ds, DATA_FILE, "action"), rf"{DATA_FILE}: no column action"),
        (lambda ds: (ds / DATA_FILE).write_bytes(b"not parquet at all"), rf"{DATA_FILE} cannot be read as parquet"),
        (lambda ds: (ds / EPISODES_FILE).write_bytes(b"PAR1"), rf"{EPISODES_FILE} cannot be read as parquet"),
    ]
    for i, (edit, message) in enumerate(cases):
        ds = tmp_path / f"bad{i}"
        shutil.copytree(exported, ds)
        edit(ds)
        with pytest.raises(LeRobotFormatError, match=message) as info:
            import_lerobot(ds, tmp_path / f"tub{i}")
        assert "\n" not in str(info.value)
        assert not (tmp_path / f"tub{i}").exists()
    assert not list(tmp_path.glob(".*partial*"))


# -- files rolling over ----------------------------------------------------------------------------------

def test_files_roll_over_and_read_back_across_them(source, tmp_path, monkeypatch):
    """Size limits of a millionth of a MB: every episode starts a new data, video and episodes file,
    two files per chunk: chunk-000/file-000, file-001, chunk-001/file-000, file-001."""
    from parts.tub.lerobot import export as export_module
    from parts.tub.lerobot.video import FrameReader

    monkeypatch.setattr(export_module, "DATA_FILES_SIZE_IN_MB", 1e-6)
    monkeypatch.setattr(export_module, "VIDEO_FILES_SIZE_IN_MB", 1e-6)
    monkeypatch.setattr(export_module, "CHUNKS_SIZE", 2)
    monkeypatch.setattr(export_module, "EPISODES_PER_GROUP", 1)
    tub, written = source
    out = tmp_path / "rolled"
    export_lerobot(tub, out)
    ds = read_dataset(out)
    info, episodes = ds["info"], ds["episodes"]
    assert (info["chunks_size"], info["data_files_size_in_mb"], info["video_files_size_in_mb"]) == (2, 1e-6, 1e-6)
    files = [(0, 0), (0, 1), (1, 0), (1, 1)]
    for folder in ("data", "meta/episodes"):
        assert sorted(chunk_file(p) for p in (out / folder).glob("chunk-*/file-*.parquet")) == files, folder
    assert [(e["data/chunk_index"], e["data/file_index"]) for e in episodes] == files
    assert [(e["meta/episodes/chunk_index"], e["meta/episodes/file_index"]) for e in episodes] == files
    # a video file counts the bytes the encoder gave out, and SVT-AV1 holds frames back (a mini-GOP,
    # given out as its threads get to it): how many of these short episodes share a file varies
    cam = "videos/observation.images.cam"
    videos = sorted(chunk_file(p) for p in (out / cam).glob("chunk-*/file-*.mp4"))
    assert len(videos) >= 2 and videos == files[:len(videos)]  # rolled over, in order
    placed = [(e[f"{cam}/chunk_index"], e[f"{cam}/file_index"]) for e in episodes]
    assert placed == sorted(placed) and sorted(set(placed)) == videos
    for i, e in enumerate(episodes):
        # an episode starts where the one before it in the same file ended, the first at 0
        start = episodes[i - 1][f"{cam}/to_timestamp"] if i and placed[i - 1] == placed[i] else 0.0
        assert e[f"{cam}/from_timestamp"] == pytest.approx(start)
        assert e[f"{cam}/to_timestamp"] == pytest.approx(start + e["length"] / info["fps"])

    # the way back reads every file: every value, every frame
    report = import_lerobot(out, tmp_path / "back")
    assert report.records == len(written) and report.episodes == 4
    for rec, (ts, values), src in zip(load_records(tmp_path / "back"), written, load_records(tub), strict=True):
        assert rec.timestamp_ms == ts and rec["sim/pos"] == values["sim/pos"]
        assert rec.angle == pytest.approx(values["user/angle"], rel=2 ** -24, abs=1e-30)
        assert np.mean(np.abs(rec.image().astype(int) - src.image().astype(int))) <= VIDEO_MEAN_ABS

    # random access: the reader seeks back and forth within files and jumps between them
    reader = FrameReader()
    order = np.random.default_rng(1).permutation(len(ds["rows"]))
    for i in order:
        row = ds["rows"][i]
        ep = episodes[row["episode_index"]]
        path = out / cam / f"chunk-{ep[f'{cam}/chunk_index']:03d}/file-{ep[f'{cam}/file_index']:03d}.mp4"
        got = reader.frame(path, ep[f"{cam}/from_timestamp"] + row["timestamp"])
        assert np.array_equal(got, ds["frames"]["observation.images.cam"][i][1]), i
    reader.close()


# -- options ---------------------------------------------------------------------------------------------

def test_a_negative_max_gap_is_an_error(source, tmp_path):
    with pytest.raises(TubError, match=r"max_gap_s must be >= 0 seconds \(0: never split on a gap\), got -1"):
        export_lerobot(source[0], tmp_path / "ds", max_gap_s=-1, video=False)
    assert not (tmp_path / "ds").exists()


def test_each_record_comes_back_under_the_angle_key_its_tub_used(donkey_tub, tmp_path):
    """DonkeyCar 4.x tubs (user/steering) and newer ones (user/angle) exported together."""
    old, old_written = donkey_tub(5, name="old", angle_key="user/steering", image_size=(48, 64))
    new, new_written = donkey_tub(4, name="new", image_size=(48, 64))
    export_lerobot([new, old], tmp_path / "ds", video=False)
    import_lerobot(tmp_path / "ds", tmp_path / "back")
    assert Tub(tmp_path / "back", read_only=True).inputs == ["cam/image_array", "user/angle", "user/throttle",
                                                              "user/mode", "user/steering"]
    back = load_records(tmp_path / "back")
    assert [sorted(k for k in r.data if k.startswith("user/")) for r in back] == \
        [["user/angle", "user/mode", "user/throttle"]] * 4 + [["user/mode", "user/steering", "user/throttle"]] * 5
    assert [r.angle for r in back] == pytest.approx([r["user/angle"] for r in new_written]
                                                    + [r["user/steering"] for r in old_written], rel=2 ** -24)
    # a dataset without tub/index in its episodes (exported before it was written): by tub/name
    _drop_column(tmp_path / "ds", EPISODES_FILE, "tub/index")
    import_lerobot(tmp_path / "ds", tmp_path / "back2")
    assert [sorted(r.data) for r in load_records(tmp_path / "back2")] == [sorted(r.data) for r in back]


def test_long_sessions_are_split_so_timestamps_keep_lerobots_tolerance(tmp_path):
    synthetic_tub(tmp_path / "t", 100)  # 5 s at 20 Hz, one session
    report = export_lerobot(tmp_path / "t", tmp_path / "ds", video=False, max_episode_s=1.5)
    ds = read_dataset(tmp_path / "ds")
    assert report.episodes == 4 and [e["length"] for e in ds["episodes"]] == [30, 30, 30, 10]
    assert max(r["timestamp"] for r in ds["rows"]) == pytest.approx(29 / 20)
    for bad in (0, -5, 2049):
        with pytest.raises(TubError, match=r"max_episode_s must be > 0 and <= 2048 s"):
            export_lerobot(tmp_path / "t", tmp_path / "x", video=False, max_episode_s=bad)


def test_the_default_episode_limit_keeps_float32_timestamps_within_1e4_s():
    """float32 has 24 bits: past 2048 s its step is 2.4e-4 s, and frame_index / fps stored as
    float32 can be up to 1.2e-4 s off (at 15, 30, 50, 60 fps), beyond the 1e-4 s LeRobot accepts."""
    from parts.tub.lerobot.export import DEFAULT_MAX_EPISODE_S, MAX_EPISODE_S

    assert DEFAULT_MAX_EPISODE_S == 1800 and MAX_EPISODE_S == 2048

    def worst(fps: int, start_s: int, end_s: int) -> float:
        t = np.arange(start_s * fps, end_s * fps, dtype=np.float64) / fps
        return float(np.max(np.abs(t.astype(np.float32).astype(np.float64) - t)))

    for fps in (10, 15, 20, 30, 50, 60):
        assert worst(fps, 0, MAX_EPISODE_S) < 1e-4
    assert [fps for fps in (10, 15, 20, 30, 50, 60) if worst(fps, MAX_EPISODE_S, MAX_EPISODE_S + 60) > 1e-4] \
        == [15, 30, 50, 60]
