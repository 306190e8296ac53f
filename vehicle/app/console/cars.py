"""The console's Cars: the cars this laptop is paired with, their live status, pulls and pushes.

Cars are kept in ``<MODELS_PATH>/.jobs/cars.json`` (readable by this user only: it holds the
pairing tokens, which the page never receives). The console talks to each car through
:class:`vehicle.app.carlink.client.CarClient` in a worker thread; a pull runs in the background
and the page polls its progress. Pulled tubs land in the console's data folder and become datasets.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vehicle.app.carlink.client import CarAddress, CarClient, CarLinkError, parse_address
from vehicle.app.console.api import ApiError, json_response, read_json
from vehicle.app.console.jsonsafe import finite

if TYPE_CHECKING:
    from vehicle.app.console.server import ConsoleApp

logger = logging.getLogger(__name__)

CARS_FILE = "cars.json"
#: most cars remembered
MAX_CARS = 50


@dataclass
class Car:
    """A paired car."""

    id: int
    name: str
    host: str
    port: int
    token: str | None

    @property
    def address(self) -> CarAddress:
        return CarAddress(self.host, self.port, self.token)

    def view(self) -> dict[str, Any]:
        """What the page gets: never the token."""
        return {"id": self.id, "name": self.name, "url": self.address.url, "paired": self.token is not None}


class CarStore:
    """The cars of ``path`` (a JSON file written atomically, mode 0600)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._lock = threading.Lock()

    def list(self) -> list[Car]:
        """Every car, in the order added."""
        try:
            data = json.loads(self.path.read_text())
            return [Car(**c) for c in data.get("cars", [])]
        except FileNotFoundError:
            return []
        except (ValueError, TypeError) as exc:
            logger.error("%s is unreadable (%s): no cars listed; fix or remove the file", self.path, exc)
            return []

    def get(self, car_id: int) -> Car:
        for car in self.list():
            if car.id == car_id:
                return car
        raise ApiError(404, f"no car {car_id}: it was removed; reload the page")

    def add(self, name: str, address: CarAddress) -> Car:
        """Add (or update, same address) a car."""
        with self._lock:
            cars = [c for c in self.list() if (c.host, c.port) != (address.host, address.port)]
            if len(cars) >= MAX_CARS:
                raise ApiError(409, f"{MAX_CARS} cars already: remove one first")
            car = Car(max([c.id for c in self.list()], default=0) + 1, name, address.host, address.port, address.token)
            self._save([*cars, car])
            return car

    def remove(self, car_id: int) -> None:
        with self._lock:
            self._save([c for c in self.list() if c.id != car_id])

    def _save(self, cars: list[Car]) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.tmp{os.getpid()}")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)  # the tokens: this user only
        with os.fdopen(fd, "w") as f:
            json.dump({"cars": [asdict(c) for c in cars]}, f, indent=1)
        os.replace(tmp, self.path)


@dataclass
class PullState:
    """A car's latest pull, as the page shows it."""

    state: str = "idle"  # idle | running | done | failed
    tub: str | None = None
    done: int = 0
    total: int = 0
    error: str | None = None
    pulled: list[dict[str, Any]] | None = None
    started: float | None = None


class CarsApi:
    """The console's /api/cars routes (see the module docstring)."""

    def __init__(self, app: ConsoleApp) -> None:
        self.app = app
        self.store = CarStore(app.jobs.jobs_dir / CARS_FILE)
        self.pulls: dict[int, PullState] = {}
        self._tasks: set[asyncio.Task[Any]] = set()
        self._closing = threading.Event()

    async def close(self) -> None:
        """Stop the running pulls at their next record (what they pulled is kept: they resume)."""
        self._closing.set()
        if self._tasks:
            await asyncio.gather(*self._tasks, return_exceptions=True)

    def routes(self) -> list[tuple[str, str, Any]]:
        return [("GET", "/api/cars", self.list_cars), ("POST", "/api/cars", self.add_car),
                ("GET", "/api/cars/discover", self.discover), ("DELETE", "/api/cars/{id}", self.remove_car),
                ("GET", "/api/cars/{id}", self.car_status), ("POST", "/api/cars/{id}/pull", self.start_pull),
                ("GET", "/api/cars/{id}/pull", self.pull_state), ("POST", "/api/cars/{id}/push", self.push),
                ("POST", "/api/cars/{id}/use", self.use)]

    def _car(self, request: Any) -> Car:
        try:
            return self.store.get(int(request.match_info["id"]))
        except ValueError:
            raise ApiError(400, "car id must be a whole number") from None

    @staticmethod
    async def _ask(func: Any, *args: Any) -> Any:
        """A blocking car request in a thread; a refusal or an unreachable car is a 502 answer."""
        try:
            return await asyncio.to_thread(func, *args)
        except CarLinkError as exc:
            status = 502 if exc.status is None else (exc.status if 400 <= exc.status < 500 else 502)
            raise ApiError(status, str(exc)) from exc

    # -- the list --------------------------------------------------------------------------------------
    async def list_cars(self, request: Any) -> Any:
        return json_response([c.view() for c in await asyncio.to_thread(self.store.list)])

    async def add_car(self, request: Any) -> Any:
        body = await read_json(request)
        try:
            address = parse_address(str(body.get("address") or ""), str(body.get("token") or "").strip() or None)
        except CarLinkError as exc:
            raise ApiError(400, str(exc), "address") from exc
        try:
            status = await asyncio.to_thread(CarClient(address, timeout=5.0).status)
        except CarLinkError as exc:
            field = "token" if exc.status in (401, 429) else "address"
            raise ApiError(400 if field == "token" else 502, str(exc), field) from exc
        name = str(body.get("name") or status.get("name") or address.host)[:63]
        car = await asyncio.to_thread(self.store.add, name, address)
        logger.info("console: car %s paired at %s", car.name, car.address.url)
        return json_response(car.view(), 201)

    async def remove_car(self, request: Any) -> Any:
        car = self._car(request)
        await asyncio.to_thread(self.store.remove, car.id)
        return json_response({"ok": True})

    async def discover(self, request: Any) -> Any:
        from vehicle.app.carlink.discovery import DiscoveryUnavailable, discover

        try:
            found = await asyncio.to_thread(discover, 2.0)
        except DiscoveryUnavailable as exc:
            return json_response({"cars": [], "error": str(exc)})
        known = {(c.host, c.port) for c in self.store.list()}
        return json_response({"cars": [{**c, "known": (c["host"], c["port"]) in known} for c in found]})

    # -- one car ---------------------------------------------------------------------------------------
    async def car_status(self, request: Any) -> Any:
        from vehicle.app.carlink.pull import plan

        car = self._car(request)
        client = CarClient(car.address, timeout=5.0)
        status = await self._ask(client.status)
        data = self.app.datasets.data_path
        tubs = await self._ask(plan, client, data, str(status.get("name") or car.name))
        models = await self._ask(client.models)
        return json_response(finite({
            "car": car.view(), "status": status, "models": models,
            "tubs": [{"name": t.name, "records": t.records, "bytes": t.bytes, "new": t.new,
                      "pulled": t.target.is_dir(), "folder": t.target.name} for t in tubs],
            "pull": asdict(self.pulls.get(car.id, PullState()))}))

    async def pull_state(self, request: Any) -> Any:
        car = self._car(request)
        return json_response(asdict(self.pulls.get(car.id, PullState())))

    async def start_pull(self, request: Any) -> Any:
        car = self._car(request)
        current = self.pulls.get(car.id)
        if current is not None and current.state == "running":
            raise ApiError(409, f"a pull from {car.name} is running already")
        state = self.pulls[car.id] = PullState("running", started=time.time())
        task = asyncio.create_task(asyncio.to_thread(self._pull, car, state))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return json_response(asdict(state), 202)

    def _pull(self, car: Car, state: PullState) -> None:
        """In a thread: pull every new record of the car into the data folder, then list them."""
        from parts.tub.errors import TubError
        from vehicle.app.carlink.pull import pull_all

        def progress(p: dict[str, Any]) -> None:
            state.tub, state.done, state.total = p["tub"], p["done"], p["total"]
            if self._closing.is_set():
                raise TubError("the console is closing: the pull goes on from here next time")

        try:
            reports = pull_all(CarClient(car.address), self.app.datasets.data_path, progress=progress)
            self.app.datasets.sync()  # the new tubs become datasets
            state.pulled = [{"folder": r.tub.name, "received": r.received, "new_tub": r.created} for r in reports]
            state.state = "done"
        except (CarLinkError, TubError, OSError) as exc:
            state.error, state.state = str(exc), "failed"
            logger.warning("console: pull from %s failed: %s", car.name, exc)
        except Exception as exc:  # a bug must still end the pull on the page
            state.error, state.state = f"{type(exc).__name__}: {exc}", "failed"
            logger.exception("console: pull from %s failed", car.name)

    async def push(self, request: Any) -> Any:
        from training.model_db import ModelDBError

        car = self._car(request)
        body = await read_json(request)
        try:
            entry = await asyncio.to_thread(self.app.db.get, str(body.get("model") or ""))
        except ModelDBError as exc:
            raise ApiError(404, str(exc), "model") from exc
        if not entry.exists:
            raise ApiError(409, f"{entry.name}'s file is missing", "model")
        client = CarClient(car.address)
        pushed = await self._ask(client.push, entry.path, f"{entry.name}.pt")
        out = {"ok": True, "model": pushed["model"], "new": pushed["new"], "switched": None}
        if body.get("use"):
            out["switched"] = (await self._ask(client.use, pushed["model"]))["switched"]
        return json_response(out)

    async def use(self, request: Any) -> Any:
        car = self._car(request)
        body = await read_json(request)
        answer = await self._ask(CarClient(car.address).use, str(body.get("model") or ""))
        return json_response(answer)
