"""The trainer console's training form: the fields a user filled in, checked against the car's
datasets, models and queue, and turned into a training job's parameters. The HTTP layer
(:mod:`vehicle.app.console.api`) only carries the answer."""

from __future__ import annotations

from typing import Any

from training import hyperparams, recipes
from training.model_db import ModelDBError, check_model_name
from vehicle.app.console.datasets import DatasetError
from vehicle.errors import VehicleError


class FormErrors(VehicleError):
    """Fields of a form that need fixing: ``errors`` maps each to its message."""

    def __init__(self, errors: dict[str, str]) -> None:
        super().__init__("; ".join(f"{k}: {v}" for k, v in errors.items()))
        self.errors = errors


def training_job(body: dict[str, Any], app: Any, names: list[str] | None) -> dict[str, Any]:
    """The parameters of a training job from the form's fields: the hyper-parameters
    (:func:`training.hyperparams.parse`, the rules ``vehicle train`` uses), the datasets, the model
    name (free in the database, the models folder and the queue), the transfer model, the recipe and
    the comment. ``app`` holds the car's datasets, model database, job queue and settings; ``names``
    are the model types.

    Raises:
        FormErrors: a message per bad field.
    """
    errors: dict[str, str] = {}
    values = body.get("hyper") if isinstance(body.get("hyper"), dict) else {}
    clean, errors = hyperparams.parse(values, model_types=names)
    ids = body.get("datasets")
    tubs: list[str] = []
    if not isinstance(ids, list) or not ids:
        errors["datasets"] = "choose at least one dataset to train on"
    else:
        for did in ids:
            try:
                if isinstance(did, bool) or not isinstance(did, int | str):
                    raise TypeError(did)  # JSON true or 1.7 is not dataset 1
                entry = app.datasets.get(int(did))
            except (DatasetError, TypeError, ValueError):
                errors["datasets"] = f"dataset {did!r} does not exist (any more); reload the page"
                break
            if entry.deleted:
                errors["datasets"] = f"{entry.name} is deleted: restore it or leave it out"
            elif not entry.path.is_dir():
                errors["datasets"] = f"{entry.name}'s folder is missing"
            else:
                tubs.append(str(entry.path))
    try:
        name = check_model_name(str(body.get("name") or ""))
        if name in app.db.names() or (app.cfg.path("MODELS_PATH") / f"{name}.pt").exists():
            errors["name"] = f"a model named {name!r} exists already; choose another name"
        if any(j.kind == "train" and j.status in ("queued", "running") and j.params.get("model_name") == name
               for j in (app.jobs.get(s["id"]) for s in app.jobs.list()) if j is not None):
            errors["name"] = f"a queued training already writes {name!r}; choose another name"
    except ValueError as exc:
        errors["name"] = str(exc)
        name = ""
    transfer = None
    if body.get("transfer"):
        try:
            entry = app.db.get(str(body["transfer"]))
            if not entry.exists:
                errors["transfer"] = f"{entry.name}'s file is missing"
            transfer = str(entry.path)
            if clean.get("model_type") and clean["model_type"] != entry.type:
                errors["model_type"] = (f"transfer starts from a {entry.type!r} model: choose {entry.type} "
                                        "or no transfer")
            clean["model_type"] = entry.type
        except ModelDBError as exc:
            errors["transfer"] = str(exc)
    recipe_name = body.get("recipe") or None
    if recipe_name is not None:
        try:
            recipe = recipes.recipe(str(recipe_name))
            if not clean.get("model_type"):
                clean["model_type"] = recipe.model_type
        except ValueError as exc:
            errors["recipe"] = str(exc)
    comment = body.get("comment")
    if comment is not None and (not isinstance(comment, str) or len(comment) > 2000):
        errors["comment"] = "must be text of at most 2000 characters"
    if errors:
        raise FormErrors(errors)
    model_type = clean.pop("model_type", None)
    return {"tubs": tubs, "datasets": [int(i) for i in ids], "model_name": name, "model_type": model_type,
            "transfer": transfer, "transfer_name": body.get("transfer") or None, "comment": comment or None,
            "hyper": clean, "settings": hyperparams.settings_for(clean), "recipe": recipe_name}
