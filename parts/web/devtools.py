"""Drive a headless chromium over the Chrome DevTools Protocol (for tests, bench and screenshots).

Uses the system chromium (Debian: ``apt-get install chromium``) and aiohttp's websocket client;
no browser download, no Playwright. Example::

    async with Chromium.launch() as browser:
        page = await browser.new_page("http://127.0.0.1:8887/")
        await page.wait_for("window.webStats && webStats.connected")
        await page.key("ArrowUp", down=True)
        png = await page.screenshot()
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import itertools
import json
import logging
import os
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path
from types import TracebackType
from typing import Any

logger = logging.getLogger(__name__)

CHROMIUM_PATHS = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-extensions", "--disable-default-apps", "--mute-audio",
         "--disable-background-timer-throttling", "--disable-renderer-backgrounding",
         "--disable-backgrounding-occluded-windows", "--remote-debugging-port=0")
#: key name -> (code, Windows virtual key code) for the keys the page uses
KEYS = {"ArrowUp": ("ArrowUp", 38), "ArrowDown": ("ArrowDown", 40), "ArrowLeft": ("ArrowLeft", 37),
        "ArrowRight": ("ArrowRight", 39), " ": ("Space", 32), "Escape": ("Escape", 27),
        "w": ("KeyW", 87), "a": ("KeyA", 65), "s": ("KeyS", 83), "d": ("KeyD", 68),
        "r": ("KeyR", 82), "m": ("KeyM", 77), "c": ("KeyC", 67)}


class DevToolsError(RuntimeError):
    """The browser could not be started or a DevTools command failed."""


def find_chromium() -> str | None:
    """Path of a chromium binary, or None."""
    for path in CHROMIUM_PATHS:
        if Path(path).is_file():
            return path
    return shutil.which("chromium")


class _Connection:
    """One DevTools websocket: numbered commands, answers matched by id."""

    def __init__(self, session: Any, ws: Any) -> None:
        self._session, self._ws = session, ws
        self._ids = itertools.count(1)
        self._waiting: dict[int, asyncio.Future[Any]] = {}
        self._reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        async for msg in self._ws:
            data = json.loads(msg.data)
            future = self._waiting.pop(data.get("id", -1), None)
            if future is not None and not future.done():
                future.set_result(data)
        for future in self._waiting.values():
            if not future.done():
                future.set_exception(DevToolsError("DevTools connection closed"))

    async def send(self, method: str, params: dict[str, Any] | None = None,
                   timeout: float = 20.0) -> dict[str, Any]:
        msg_id = next(self._ids)
        future: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        self._waiting[msg_id] = future
        await self._ws.send_str(json.dumps({"id": msg_id, "method": method, "params": params or {}}))
        data = await asyncio.wait_for(future, timeout)
        if "error" in data:
            raise DevToolsError(f"{method}: {data['error'].get('message', data['error'])}")
        return data.get("result", {})

    async def close(self) -> None:
        await self._ws.close()
        self._reader.cancel()
        await asyncio.gather(self._reader, return_exceptions=True)


class Page:
    """A browser tab."""

    def __init__(self, browser: Chromium, target_id: str, conn: _Connection) -> None:
        self.browser, self.target_id, self._conn = browser, target_id, conn

    async def send(self, method: str, params: dict[str, Any] | None = None) -> dict[str, Any]:
        """Send a raw DevTools command to the tab."""
        return await self._conn.send(method, params)

    async def evaluate(self, expression: str) -> Any:
        """Evaluate JavaScript in the page and return its (JSON) value; awaits promises."""
        res = await self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                    "awaitPromise": True})
        if "exceptionDetails" in res:
            raise DevToolsError(f"{expression!r} threw: {res['exceptionDetails'].get('text')}")
        return res.get("result", {}).get("value")

    async def wait_for(self, expression: str, timeout: float = 10.0) -> Any:
        """Poll ``expression`` until it is truthy; return its value."""
        end = time.monotonic() + timeout
        error: Exception | None = None
        while True:
            try:
                value = await self.evaluate(expression)
            except DevToolsError as exc:  # e.g. the page is still loading
                value, error = None, exc
            if value:
                return value
            if time.monotonic() > end:
                raise TimeoutError(f"page condition not met within {timeout} s: {expression}"
                                   + (f" (last error: {error})" if error else ""))
            await asyncio.sleep(0.02)

    async def key(self, key: str, down: bool = True) -> None:
        """Press (``down=True``) or release a key named as in :data:`KEYS`."""
        code, vk = KEYS[key]
        await self.send("Input.dispatchKeyEvent", {
            "type": "keyDown" if down else "keyUp", "key": key, "code": code,
            "windowsVirtualKeyCode": vk, "nativeVirtualKeyCode": vk})

    async def viewport(self, width: int, height: int, scale: float = 1.0, mobile: bool = False) -> None:
        """Emulate a screen size (e.g. a phone)."""
        await self.send("Emulation.setDeviceMetricsOverride", {
            "width": width, "height": height, "deviceScaleFactor": scale, "mobile": mobile})

    async def screenshot(self) -> bytes:
        """PNG of the visible page."""
        res = await self.send("Page.captureScreenshot", {"format": "png"})
        return base64.b64decode(res["data"])

    async def close(self) -> None:
        """Close the tab (its connections close, as when a user closes it)."""
        await self._conn.close()
        await self.browser._browser.send("Target.closeTarget", {"targetId": self.target_id})


class Chromium:
    """A headless chromium process with a DevTools endpoint. Use ``async with Chromium.launch()``."""

    def __init__(self, binary: str | None = None, window: tuple[int, int] = (1280, 900)) -> None:
        found = binary or find_chromium()
        if found is None:
            raise DevToolsError("chromium not found: install it (Debian: apt-get install chromium)")
        self.binary, self.window = found, window
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        self._proc: subprocess.Popen[bytes] | None = None
        self._session: Any = None
        self._browser: _Connection = None  # type: ignore[assignment]
        self.port = 0

    @classmethod
    def launch(cls, binary: str | None = None, window: tuple[int, int] = (1280, 900)) -> Chromium:
        """A browser to start with ``async with``."""
        return cls(binary, window)

    async def __aenter__(self) -> Chromium:
        import aiohttp

        self._tmp = tempfile.TemporaryDirectory(prefix="chromium-", ignore_cleanup_errors=True)
        profile = Path(self._tmp.name)
        self._proc = subprocess.Popen(  # noqa: S603 - fixed binary and flags
            [self.binary, *FLAGS, f"--user-data-dir={profile}",
             f"--window-size={self.window[0]},{self.window[1]}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True)  # its own process group: its helper processes end with it
        port_file = profile / "DevToolsActivePort"
        end = time.monotonic() + 20
        while not port_file.is_file() or not port_file.read_text().strip():
            if self._proc.poll() is not None or time.monotonic() > end:
                await self.__aexit__(None, None, None)
                raise DevToolsError(f"{self.binary} did not open its DevTools port")
            await asyncio.sleep(0.05)
        lines = port_file.read_text().split()
        self.port, path = int(lines[0]), lines[1]
        self._session = aiohttp.ClientSession()
        ws = await self._session.ws_connect(f"ws://127.0.0.1:{self.port}{path}", max_msg_size=0)
        self._browser = _Connection(self._session, ws)
        return self

    async def new_page(self, url: str) -> Page:
        """Open ``url`` in a new tab."""
        res = await self._browser.send("Target.createTarget", {"url": "about:blank"})
        target = res["targetId"]
        ws = await self._session.ws_connect(
            f"ws://127.0.0.1:{self.port}/devtools/page/{target}", max_msg_size=0)
        page = Page(self, target, _Connection(self._session, ws))
        await page.send("Page.enable")
        await page.send("Page.navigate", {"url": url})
        await page.wait_for(f"location.href === {json.dumps(url)} && document.readyState === 'complete'")
        return page

    async def __aexit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                        tb: TracebackType | None) -> None:
        if self._browser is not None:
            await self._browser.close()
        if self._session is not None:
            await self._session.close()
        if self._proc is not None and self._proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self._proc.pid, signal.SIGTERM)  # the group of the browser we started
            try:
                await asyncio.to_thread(self._proc.wait, 5)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self._proc.pid, signal.SIGKILL)
                await asyncio.to_thread(self._proc.wait)
        if self._tmp is not None:
            self._tmp.cleanup()
