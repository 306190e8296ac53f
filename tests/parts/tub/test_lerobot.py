"""LeRobot v3.0 export and import: every file read back with pyarrow and PyAV and checked against the
schema; round trips tub -> LeRobot -> tub; datasets written by LeRobot itself imported."""

from __future__ import annotations

import json
import math
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


def read_dataset(root: Path) -> dict[str, Any]:
    """Every file of a v3.0 dataset, checked against info.json on the way."""
    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["chunks_size"] == 1000 and info["data_files_size_in_mb"] == 100
    assert info["splits"] == {"train": f"0:{info['total_episodes']}"}
    features = info["features"]
    for name, default in (("timestamp", "float32"), ("frame_index", "int64"), ("episode_index", "int64"),
                          ("index", "int64"), ("task_index", "int64")):
        assert features[name] == {"dtype": default, "shape": [1], "names": None}
    assert "/" not in "".join(features)  # LeRobot forbids "/" in feature names
    videos = [k for k, f in features.items() if f["dtype"] == "video"]
    assert (info["video_path"] is not None) == bool(videos)
    if videos:
        assert info["video_path"] == "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"

    tables = [pq.read_table(p) for p in sorted((root / "data").glob("chunk-*/file-*.parquet"))]
    data = pa.concat_tables(tables)
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

    episodes = pa.concat_tables([pq.read_table(p) for p in
                                 sorted((root / "meta/episodes").glob("chunk-*/file-*.parquet"))]).to_pylist()
    assert [e["episode_index"] for e in episodes] == list(range(info["total_episodes"]))
    end = 0
    video_end: dict[str, float] = {}
    fps = info["fps"]
    for ep in episodes:
        mine = [r for r in rows if r["episode_index"] == ep["episode_index"]]
        assert ep["dataset_from_index"] == end == mine[0]["index"]
        assert ep["dataset_to_index"] == end + ep["length"] == mine[-1]["index"] + 1
        end = ep["dataset_to_index"]
        assert [r["frame_index"] for r in mine] == list(range(ep["length"]))
        for r in mine:  # LeRobot finds a video frame at from_timestamp + timestamp, frame_index / fps
            assert r["timestamp"] == pytest.approx(r["frame_index"] / fps, abs=1e-6)
        assert set(ep["tasks"]) == {tasks[r["task_index"]] for r in mine}
        assert ep["data/chunk_index"] == 0 and ep["data/file_index"] == 0
        for key in videos:
            assert ep[f"videos/{key}/from_timestamp"] == pytest.approx(video_end.get(key, 0.0))
            assert ep[f"videos/{key}/to_timestamp"] == pytest.approx(ep[f"videos/{key}/from_timestamp"]
                                                                     + ep["length"] / fps)
            video_end[key] = ep[f"videos/{key}/to_timestamp"]
        for name, ft in features.items():
            if ft["dtype"] == "string":
                assert f"stats/{name}/mean" not in ep
                continue
            shape = (ft["shape"][2], 1, 1) if ft["dtype"] in ("video", "image") else (ft["shape"][0],)
            for stat in ("min", "max", "mean", "std", "q01", "q10", "q50", "q90", "q99"):
                assert np.asarray(ep[f"stats/{name}/{stat}"]).shape == shape, (name, stat)
            if ft["dtype"] not in ("video", "image"):
                check_stats(ep, f"stats/{name}/", column(mine, name, ft))
    stats = json.loads((root / "meta/stats.json").read_text())
    assert set(stats) == {k for k, f in features.items() if f["dtype"] != "string"}
    for name, ft in features.items():
        if ft["dtype"] not in ("video", "image", "string"):
            check_stats({f"{name}/{k}": v for k, v in stats[name].items()}, f"{name}/", column(rows, name, ft))

    frames: dict[str, list[tuple[float, np.ndarray]]] = {}
    for key in videos:
        vinfo = features[key]["info"]
        assert vinfo["video.codec"] == "av1" and vinfo["video.pix_fmt"] == "yuv420p"
        assert vinfo["video.fps"] == fps and vinfo["has_audio"] is False
        assert [vinfo["video.height"], vinfo["video.width"], vinfo["video.channels"]] == features[key]["shape"]
        decoded = []
        for path in sorted((root / "videos" / key).glob("chunk-*/file-*.mp4")):
            with av.open(str(path)) as container:
                stream = container.streams.video[0]
                assert stream.codec_context.name in ("libdav1d", "av1") and stream.pix_fmt == "yuv420p"
                decoded += [(float(f.time), f.to_ndarray(format="rgb24")) for f in container.decode(stream)]
        assert len(decoded) == info["total_frames"]
        frames[key] = decoded
        for r in rows:  # the frame LeRobot would look up for each row, within its 1e-4 s tolerance
            ep = episodes[r["episode_index"]]
            t = ep[f"videos/{key}/from_timestamp"] + r["timestamp"]
            assert abs(decoded[r["index"]][0] - t) < 1e-4
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
    assert (episodes[3]["tub/first_index"], episodes[3]["tub/last_index"]) == (40, 54)
    # image statistics: per channel, in [0, 1], from every source frame
    src = np.stack([r.image() for r in load_records(tub)]).astype(np.float64) / 255
    img = ds["stats"]["observation.images.cam"]
    assert np.asarray(img["mean"]).shape == (3, 1, 1) and img["count"] == [52]
    np.testing.assert_allclose(np.asarray(img["mean"]).ravel(), src.mean(axis=(0, 1, 2)), atol=1e-9)
    np.testing.assert_allclose(np.asarray(img["std"]).ravel(), src.std(axis=(0, 1, 2)), atol=1e-9)
    np.testing.assert_allclose(np.asarray(img["q50"]).ravel(), np.quantile(src, 0.5, axis=(0, 1, 2),
                                                                           method="inverted_cdf"), atol=1e-9)
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
