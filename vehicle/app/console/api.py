"""The console's JSON API: datasets, training and evaluation jobs, models and the leaderboard.

Every handler answers JSON; a user's mistake is a 4xx answer ``{"error": message, "field": name}``
(or ``{"errors": {field: message}}`` for a form) that the page shows next to the field. Blocking
work (SQLite, reading tubs) runs in a thread so the event loop keeps streaming progress.
"""

from __future__ import annotations

import asyncio
import json
import logging
import re
import sys
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from training import hyperparams, recipes
from training.model_db import ModelDBError, check_model_name
from vehicle.app.console.datasets import DatasetError, augmentation_preview
from vehicle.app.console.jsonsafe import finite
from vehicle.app.console.training_form import FormErrors, training_job
from vehicle.errors import VehicleError

if TYPE_CHECKING:
    from vehicle.app.console.server import ConsoleApp

logger = logging.getLogger(__name__)

#: largest JSON body accepted, bytes
MAX_BODY = 256 * 1024
Handler = Callable[[Any], Awaitable[Any]]


class ApiError(Exception):
    """An answer with an error status: ``message`` for the page, ``field`` it belongs to."""

    def __init__(self, status: int, message: str, field: str | None = None,
                 errors: dict[str, str] | None = None) -> None:
        super().__init__(message)
        self.status, self.message, self.field, self.errors = status, message, field, errors


def json_response(data: Any, status: int = 200) -> Any:
    """A JSON answer that is never cached."""
    from aiohttp import web

    return web.json_response(data, status=status, headers={"Cache-Control": "no-store"},
                             dumps=lambda d: json.dumps(d, default=str, allow_nan=False))


async def read_json(request: Any) -> dict[str, Any]:
    """The request's JSON object body (ApiError 400/415 otherwise)."""
    if request.content_type != "application/json":
        raise ApiError(415, "send the body as application/json")
    if request.content_length is not None and request.content_length > MAX_BODY:
        raise ApiError(413, f"request body over {MAX_BODY} bytes")
    try:
        data = json.loads(await request.text())
    except ValueError as exc:
        raise ApiError(400, f"the body is not valid JSON: {exc}") from exc
    except RecursionError:  # json's decoder recurses once per [ or {: a hostile body exhausts the stack
        raise ApiError(400, "the body is nested too deeply: send a flat JSON object") from None
    if not isinstance(data, dict):
        raise ApiError(400, "the body must be a JSON object")
    return data


def _int(text: str, what: str) -> int:
    try:
        return int(text)
    except (TypeError, ValueError):
        raise ApiError(400, f"{what} must be a whole number, got {text!r}") from None


class Api:
    """Route handlers bound to one :class:`~vehicle.app.console.server.ConsoleApp`."""

    def __init__(self, app: ConsoleApp) -> None:
        self.app = app

    @property
    def store(self) -> Any:
        return self.app.datasets

    @property
    def db(self) -> Any:
        return self.app.db

    def routes(self) -> list[tuple[str, str, Handler]]:
        """(method, path, handler) of every API route."""
        return [
            ("GET", "/api/info", self.info),
            ("GET", "/api/datasets", self.list_datasets),
            ("POST", "/api/datasets", self.add_dataset),
            ("POST", "/api/datasets/import-udacity", self.import_udacity),
            ("GET", "/api/datasets/{id}", self.get_dataset),
            ("PATCH", "/api/datasets/{id}", self.edit_dataset),
            ("DELETE", "/api/datasets/{id}", self.purge_dataset),
            ("POST", "/api/datasets/{id}/delete", self.delete_dataset),
            ("POST", "/api/datasets/{id}/restore", self.restore_dataset),
            ("POST", "/api/datasets/{id}/forget", self.forget_dataset),
            ("GET", "/api/datasets/{id}/series", self.dataset_series),
            ("POST", "/api/datasets/{id}/records", self.mark_records),
            ("GET", "/api/datasets/{id}/records/{index}", self.get_record),
            ("GET", "/api/datasets/{id}/images/{index}", self.get_image),
            ("GET", "/api/datasets/{id}/movie", self.dataset_movie),
            ("GET", "/api/augment-preview", self.augment_preview),
            ("POST", "/api/train/validate", self.validate_training),
            ("POST", "/api/jobs/train", self.submit_training),
            ("POST", "/api/jobs/evaluate", self.submit_evaluation),
            ("GET", "/api/jobs", self.list_jobs),
            ("GET", "/api/jobs/{id}", self.get_job),
            ("POST", "/api/jobs/{id}/cancel", self.cancel_job),
            ("GET", "/api/models", self.list_models),
            ("GET", "/api/models/{name}", self.get_model),
            ("PATCH", "/api/models/{name}", self.edit_model),
            ("DELETE", "/api/models/{name}", self.delete_model),
            ("POST", "/api/models/{name}/export", self.export_model),
            ("GET", "/api/models/{name}/file", self.model_file),
            ("GET", "/api/models/{name}/saliency", self.model_saliency),
            ("GET", "/api/models/{name}/saliency/{file}", self.model_saliency_file),
            ("GET", "/api/evaluations/{id}/picture", self.evaluation_picture),
            ("GET", "/api/evaluations/{id}/gallery", self.evaluation_gallery),
            ("GET", "/api/evaluations/{id}/gallery/{path:.+}", self.evaluation_gallery_file),
            ("DELETE", "/api/evaluations/{id}", self.delete_evaluation),
            ("GET", "/api/leaderboard", self.leaderboard),
        ]

    async def _run(self, func: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Run blocking work in a thread; map library errors to answers."""
        try:
            return await asyncio.to_thread(func, *args, **kwargs)
        except DatasetError as exc:
            raise ApiError(exc.status, str(exc), exc.field) from exc
        except ModelDBError as exc:
            status = 404 if str(exc).startswith("no ") else 409
            raise ApiError(status, str(exc)) from exc
        except (VehicleError, ValueError, OSError) as exc:
            raise ApiError(400, str(exc)) from exc

    # -- info -------------------------------------------------------------------------------------
    async def info(self, request: Any) -> Any:
        cfg = self.app.cfg
        types = await self.app.model_types()
        return json_response(finite({
            "car": str(cfg.CAR_PATH), "car_name": Path(cfg.CAR_PATH).name, "data_path": str(self.store.data_path),
            "models_path": str(cfg.path("MODELS_PATH")), "db": str(self.db.db_path),
            "hyperparams": hyperparams.describe(cfg, [t["name"] for t in types] if types else None),
            "model_types": types, "eval_tracks": list(cfg.SIM_EVAL_TRACK_SEEDS), "eval_laps": cfg.SIM_EVAL_LAPS,
            "train_tracks": list(cfg.SIM_TRACK_SEEDS), "default_model_name": self.app.free_model_name(),
            "recipes": recipes.describe(),
        }))

    # -- datasets ---------------------------------------------------------------------------------
    async def list_datasets(self, request: Any) -> Any:
        def work() -> list[dict[str, Any]]:
            return [self.store.summary(e) for e in self.store.sync()]

        return json_response(finite(await self._run(work)))

    async def get_dataset(self, request: Any) -> Any:
        entry = await self._run(self.store.get, _int(request.match_info["id"], "dataset id"))
        return json_response(finite(await self._run(self.store.summary, entry)))

    async def add_dataset(self, request: Any) -> Any:
        body = await read_json(request)
        action = body.get("action", "create")
        if action == "create":
            entry = await self._run(self.store.create, body.get("name", ""), body.get("label"), body.get("comment"))
            entries = [entry]
        elif action == "register":
            entries = await self._run(self.store.register, body.get("path", ""), body.get("label"),
                                      body.get("comment"))
        else:
            raise ApiError(400, f"action must be create or register, got {action!r}", "action")
        return json_response(finite([await self._run(self.store.summary, e) for e in entries]), 201)

    async def import_udacity(self, request: Any) -> Any:
        body = await read_json(request)
        entry = await self._run(self.store.import_udacity, body.get("source", ""), body.get("name", ""),
                                body.get("label"), body.get("comment"))
        return json_response(finite(await self._run(self.store.summary, entry)), 201)

    async def edit_dataset(self, request: Any) -> Any:
        body = await read_json(request)
        did = _int(request.match_info["id"], "dataset id")
        kwargs = {k: body[k] for k in ("label", "comment") if k in body}
        entry = await self._run(self.store.edit, did, body.get("name"), **kwargs)
        return json_response(finite(await self._run(self.store.summary, entry)))

    async def delete_dataset(self, request: Any) -> Any:
        entry = await self._run(self.store.soft_delete, _int(request.match_info["id"], "dataset id"))
        return json_response(finite(await self._run(self.store.summary, entry)))

    async def restore_dataset(self, request: Any) -> Any:
        entry = await self._run(self.store.restore, _int(request.match_info["id"], "dataset id"))
        return json_response(finite(await self._run(self.store.summary, entry)))

    async def purge_dataset(self, request: Any) -> Any:
        await self._run(self.store.purge, _int(request.match_info["id"], "dataset id"))
        return json_response({"ok": True})

    async def forget_dataset(self, request: Any) -> Any:
        await self._run(self.store.forget, _int(request.match_info["id"], "dataset id"))
        return json_response({"ok": True})

    async def dataset_series(self, request: Any) -> Any:
        entry = await self._run(self.store.get, _int(request.match_info["id"], "dataset id"))
        return json_response(await self._run(self.store.series, entry))

    async def mark_records(self, request: Any) -> Any:
        body = await read_json(request)
        action = body.get("action")
        if action not in ("delete", "restore"):
            raise ApiError(400, "action must be delete or restore", "action")
        did = _int(request.match_info["id"], "dataset id")
        out = await self._run(self.store.mark_records, did, body.get("start"), body.get("end"), action == "delete")
        return json_response(finite(out))

    async def get_record(self, request: Any) -> Any:
        entry = await self._run(self.store.get, _int(request.match_info["id"], "dataset id"))
        rec = await self._run(self.store.record, entry, _int(request.match_info["index"], "record index"))
        return json_response(finite(rec))

    async def get_image(self, request: Any) -> Any:
        from aiohttp import web

        entry = await self._run(self.store.get, _int(request.match_info["id"], "dataset id"))
        path = await self._run(self.store.image_path, entry, _int(request.match_info["index"], "record index"))
        ctype = "image/png" if path.suffix.lower() == ".png" else "image/jpeg"
        # the image of an index never changes (tubs only append): cache it in the browser
        return web.FileResponse(path, headers={"Content-Type": ctype, "Cache-Control": "private, max-age=3600"})

    async def augment_preview(self, request: Any) -> Any:
        from aiohttp import web

        from training.augment import AugmentSettings

        q = dict(request.query)
        ids = [_int(x, "dataset id") for x in q.pop("datasets", "").split(",") if x.strip()]
        seed = _int(q.pop("seed", "0"), "seed")
        if not ids:
            raise ApiError(400, "choose at least one dataset to preview", "datasets")
        values = {k: v for k, v in q.items() if k == "augmentations" or k.startswith("aug_")}
        clean, errors = hyperparams.parse(values)
        if errors:
            raise ApiError(400, "fix the augmentation settings first", errors=errors)
        cfg = self.app.cfg.replace(**hyperparams.settings_for(clean))
        entries = [await self._run(self.store.get, i) for i in ids]
        tubs = [e.path for e in entries if e.path.is_dir()]
        if not tubs:
            raise ApiError(409, "the chosen datasets' folders are missing", "datasets")
        try:
            settings = AugmentSettings.from_config(cfg)
        except ValueError as exc:
            raise ApiError(400, str(exc)) from exc
        png = await self._run(augmentation_preview, tubs, settings, 3, 5, seed)
        return web.Response(body=png, headers={"Content-Type": "image/png", "Cache-Control": "no-store"})

    # -- training -----------------------------------------------------------------------------------
    async def _model_type_names(self) -> list[str] | None:
        types = await self.app.model_types()
        return [t["name"] for t in types] if types else None

    async def validate_training(self, request: Any) -> Any:
        body = await read_json(request)
        values = body.get("hyper") if isinstance(body.get("hyper"), dict) else {}
        clean, errors = hyperparams.parse(values, model_types=await self._model_type_names())
        return json_response({"ok": not errors, "errors": errors, "values": clean})

    def _check_training(self, body: dict[str, Any], names: list[str] | None) -> dict[str, Any]:
        """The job's parameters (:func:`training_job`), or ApiError 400 with a message per bad field."""
        try:
            return training_job(body, self.app, names)
        except FormErrors as exc:
            raise ApiError(400, "some fields need fixing", errors=exc.errors) from exc

    async def submit_training(self, request: Any) -> Any:
        body = await read_json(request)
        names = await self._model_type_names()
        params = await self._run(self._check_training, body, names)
        title = f"train {params['model_name']} ({params['model_type'] or self.app.cfg.DEFAULT_MODEL_TYPE})"
        job = self.app.jobs.submit("train", title, params)
        return json_response(job.snapshot(), 201)

    async def submit_evaluation(self, request: Any) -> Any:
        body = await read_json(request)
        errors: dict[str, str] = {}
        try:
            entry = await self._run(self.db.get, str(body.get("model") or ""))
            if not entry.exists:
                errors["model"] = f"{entry.name}'s file is missing"
        except ApiError as exc:
            errors["model"] = exc.message
            entry = None
        tracks = body.get("tracks")
        if isinstance(tracks, str):
            tracks = [t for t in re.split(r"[,\s]+", tracks.strip()) if t]
        try:
            seeds = [int(t) for t in tracks] if isinstance(tracks, list) else []
            if not seeds or any(isinstance(t, bool) or str(t).strip() != str(int(t)) for t in tracks):
                raise ValueError
            if len(seeds) > 20 or any(s < 0 for s in seeds):
                raise ValueError
        except (TypeError, ValueError):
            errors["tracks"] = "give 1 to 20 track seeds (whole numbers ≥ 0), e.g. 101, 102, 103"
            seeds = []
        laps = body.get("laps")
        if isinstance(laps, bool) or not (isinstance(laps, int) or (isinstance(laps, str) and laps.strip().isdigit())) \
                or not 1 <= int(laps) <= 20:
            errors["laps"] = "must be a whole number from 1 to 20"
        if errors:
            raise ApiError(400, "some fields need fixing", errors=errors)
        assert entry is not None  # noqa: S101 - errors were raised above
        params = {"model": entry.name, "tracks": sorted(set(seeds)), "laps": int(laps)}
        job = self.app.jobs.submit("evaluate", f"evaluate {entry.name} on tracks "
                                   f"{','.join(map(str, params['tracks']))}", params)
        return json_response(job.snapshot(), 201)

    # -- jobs -----------------------------------------------------------------------------------------
    async def list_jobs(self, request: Any) -> Any:
        return json_response(finite(self.app.jobs.list()))

    def _job(self, request: Any) -> Any:
        job = self.app.jobs.get(_int(request.match_info["id"], "job id"))
        if job is None:
            raise ApiError(404, f"no job {request.match_info['id']}")
        return job

    async def get_job(self, request: Any) -> Any:
        return json_response(finite(self._job(request).snapshot()))

    async def cancel_job(self, request: Any) -> Any:
        job = self._job(request)
        if job.status not in ("queued", "running"):
            raise ApiError(409, f"job {job.id} is {job.status}: nothing to cancel")
        job = await self.app.jobs.cancel(job.id)
        return json_response(finite(job.summary()))

    # -- models -----------------------------------------------------------------------------------
    def _model_view(self, entry: Any, latest: Any) -> dict[str, Any]:
        d = entry.as_dict()
        d["id"] = entry.id
        d["dataset_names"] = [Path(p).name for p in entry.datasets]
        d["latest_evaluation"] = latest.as_dict() if latest is not None else None
        d["files"] = {kind: entry.path.with_name(entry.path.stem + suffix).is_file()
                      for kind, suffix in (("onnx", ".onnx"), ("torchscript", ".ts"))}
        return d

    async def list_models(self, request: Any) -> Any:
        def work() -> list[dict[str, Any]]:
            latest: dict[str, Any] = {}
            for ev in self.db.evaluations():
                latest.setdefault(ev.model, ev)
            return [self._model_view(e, latest.get(e.name)) for e in reversed(self.db.list())]

        return json_response(finite(await self._run(work)))

    async def get_model(self, request: Any) -> Any:
        def work() -> dict[str, Any]:
            entry = self.db.get(request.match_info["name"])
            evals = self.db.evaluations(entry.name)
            view = self._model_view(entry, evals[0] if evals else None)
            view["evaluations"] = [e.as_dict() for e in evals]
            by_path = {str(d.path): d for d in self.db.datasets()}
            view["dataset_links"] = [{"path": p, "name": Path(p).name,
                                      "id": by_path[p].id if p in by_path else None} for p in entry.datasets]
            return view

        return json_response(finite(await self._run(work)))

    def _refuse_if_in_use(self, name: str, what: str) -> None:
        """ApiError 409 when a queued or running job evaluates the model ``name`` or trains from it:
        deleting or renaming it under the job would make the job fail and lose its result."""
        for summary in self.app.jobs.list():
            if summary["status"] not in ("queued", "running", "cancelling"):
                continue
            job = self.app.jobs.get(summary["id"])
            if job is None:
                continue
            if job.kind == "evaluate" and job.params.get("model") == name:
                use = "evaluates it"
            elif job.kind == "train" and job.params.get("transfer_name") == name:
                use = "trains from it"
            else:
                continue
            raise ApiError(409, f"cannot {what} {name}: job {job.id} ({job.status}) {use}; wait for it to "
                                "finish or cancel it")

    async def edit_model(self, request: Any) -> Any:
        body = await read_json(request)
        name = request.match_info["name"]
        if body.get("name") is not None and str(body["name"]).strip() != name:
            self._refuse_if_in_use(name, "rename")

        def work() -> Any:
            entry = self.db.get(name)
            if "comment" in body:
                c = body["comment"]
                if c is not None and (not isinstance(c, str) or len(c) > 2000):
                    raise ApiError(400, "must be text of at most 2000 characters", "comment")
                entry = self.db.set_comment(entry.name, (c or "").strip() or None)
            if body.get("name") is not None and str(body["name"]).strip() != entry.name:
                try:
                    old = entry.name
                    entry = self.db.rename(entry.name, str(body["name"]))
                    self.app.jobs.model_renamed(old, entry.name)
                except ModelDBError as exc:
                    raise ApiError(409 if "exists" in str(exc) or "already" in str(exc) else 400,
                                   str(exc), "name") from exc
            return entry

        try:
            entry = await asyncio.to_thread(work)
        except ModelDBError as exc:
            raise ApiError(404, str(exc)) from exc
        return json_response(finite({"name": entry.name, "comment": entry.comment}))

    async def delete_model(self, request: Any) -> Any:
        files = request.query.get("files", "1") not in ("0", "false", "no")
        self._refuse_if_in_use(request.match_info["name"], "delete")
        deleted = await self._run(self.db.remove, request.match_info["name"], files)
        return json_response({"ok": True, "deleted": [str(p) for p in deleted]})

    async def export_model(self, request: Any) -> Any:
        body = await read_json(request)
        fmt = body.get("format")
        if fmt not in ("onnx", "torchscript"):
            raise ApiError(400, "format must be onnx or torchscript", "format")
        entry = await self._run(self.db.get, request.match_info["name"])
        if not entry.exists:
            raise ApiError(409, f"{entry.name}'s file {entry.path} is missing")
        # torch stays out of the web server: the export runs in a short-lived worker process
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "vehicle.app.console.worker", "export", "--car", str(self.app.cfg.CAR_PATH),
            entry.name, fmt, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
            cwd=str(self.app.cfg.CAR_PATH))
        out, err = await proc.communicate()
        try:
            answer = json.loads(out.decode().strip().splitlines()[-1])
        except (ValueError, IndexError):
            answer = {"error": err.decode(errors="replace").strip().splitlines()[-1:] or ["export failed"]}
        if proc.returncode != 0 or "error" in answer:
            raise ApiError(400, f"export of {entry.name} failed: {answer.get('error')}")
        return json_response(answer)

    async def model_file(self, request: Any) -> Any:
        from aiohttp import web

        fmt = request.query.get("format", "pt")
        suffix = {"pt": ".pt", "onnx": ".onnx", "torchscript": ".ts"}.get(fmt)
        if suffix is None:
            raise ApiError(400, "format must be pt, onnx or torchscript")
        entry = await self._run(self.db.get, request.match_info["name"])
        path = entry.path.with_name(entry.path.stem + suffix) if suffix != ".pt" else entry.path
        if not path.is_file():
            raise ApiError(404, f"{path.name} does not exist" + ("; export it first" if suffix != ".pt" else ""))
        return web.FileResponse(path, headers={"Content-Disposition": f'attachment; filename="{path.name}"',
                                               "Content-Type": "application/octet-stream"})

    async def evaluation_picture(self, request: Any) -> Any:
        from aiohttp import web

        png = await self._run(self.db.evaluation_picture, _int(request.match_info["id"], "evaluation id"))
        if not png:
            raise ApiError(404, "this evaluation has no picture")
        return web.Response(body=png, headers={"Content-Type": "image/png", "Cache-Control": "private, max-age=3600"})

    # -- insight: galleries, saliency, movies (vehicle/app/console/insight.py) ----------------------------
    @staticmethod
    def _file(path: Path) -> Any:
        from aiohttp import web

        from vehicle.app.console.insight import CONTENT_TYPES

        return web.FileResponse(path, headers={"Content-Type": CONTENT_TYPES[path.suffix],
                                               "Cache-Control": "private, max-age=60"})

    async def evaluation_gallery(self, request: Any) -> Any:
        from vehicle.app.console.insight import gallery_data

        eid = _int(request.match_info["id"], "evaluation id")
        return json_response(finite(await self._run(gallery_data, self.db, eid)))

    async def evaluation_gallery_file(self, request: Any) -> Any:
        from vehicle.app.console.insight import gallery_file

        eid = _int(request.match_info["id"], "evaluation id")
        return self._file(await self._run(gallery_file, self.db, eid, request.match_info["path"]))

    async def dataset_movie(self, request: Any) -> Any:
        from vehicle.app.console.insight import dataset_movie

        entry = await self._run(self.store.get, _int(request.match_info["id"], "dataset id"))
        return self._file(await self._run(dataset_movie, self.app.cfg, Path(entry.path), entry.id))

    async def model_saliency(self, request: Any) -> Any:
        """Saliency samples of a model on its datasets, computed by a worker process (torch stays out
        of the web server) once per model file."""
        from vehicle.app.console.insight import saliency_folder

        entry = await self._run(self.db.get, request.match_info["name"])
        if not entry.exists:
            raise ApiError(409, f"{entry.name}'s file {entry.path} is missing")
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "vehicle.app.console.worker", "saliency", "--car", str(self.app.cfg.CAR_PATH),
            entry.name, str(saliency_folder(self.app.cfg, entry.name)), stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE, cwd=str(self.app.cfg.CAR_PATH))
        out, err = await proc.communicate()
        try:
            answer = json.loads(out.decode().strip().splitlines()[-1])
        except (ValueError, IndexError):
            answer = {"error": (err.decode(errors="replace").strip().splitlines() or ["saliency failed"])[-1]}
        if proc.returncode != 0 or "error" in answer:
            raise ApiError(400, f"no saliency for {entry.name}: {answer.get('error')}")
        answer["base"] = f"api/models/{entry.name}/saliency/"
        return json_response(finite(answer))

    async def model_saliency_file(self, request: Any) -> Any:
        from vehicle.app.console.insight import saliency_file

        name = check_model_name(request.match_info["name"])
        return self._file(await self._run(saliency_file, self.app.cfg, name, request.match_info["file"]))

    async def delete_evaluation(self, request: Any) -> Any:
        await self._run(self.db.remove_evaluation, _int(request.match_info["id"], "evaluation id"))
        return json_response({"ok": True})

    async def leaderboard(self, request: Any) -> Any:
        text = request.query.get("tracks")
        laps_q = request.query.get("laps")

        def work() -> dict[str, Any]:
            sets = self.db.track_sets()
            if text:
                tracks = [_int(t, "track seed") for t in text.split(",") if t.strip()]
            else:
                default = tuple(sorted(self.app.cfg.SIM_EVAL_TRACK_SEEDS))
                tracks = list(default if any(t == default for t, _l, _n in sets) or not sets else sets[0][0])
            laps = _int(laps_q, "laps") if laps_q else None
            board = self.db.leaderboard(tracks, laps)
            return {"tracks": sorted(tracks), "laps": laps,
                    "track_sets": [{"tracks": list(t), "laps": lp, "models": n} for t, lp, n in sets],
                    "board": [e.as_dict() for e in board]}

        return json_response(finite(await self._run(work)))
