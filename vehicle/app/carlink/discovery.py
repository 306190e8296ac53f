"""Finding cars that announce themselves on the local network (:mod:`parts.web.announce`).

Listens for ``timeout`` seconds with python-zeroconf (``pip install zeroconf``). A network that
drops multicast (many guest and campus Wi-Fis) shows no car: the user adds it by address.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from parts.web.announce import SERVICE_TYPE
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


class DiscoveryUnavailable(UserError):
    """zeroconf is not installed."""


def discover(timeout: float = 2.0, interfaces: Any = None) -> list[dict[str, Any]]:
    """Cars heard within ``timeout`` seconds: ``[{"name", "host", "port", "url"}]`` by name (the URL
    has no token: the user pairs with the one the car shows)."""
    try:
        from zeroconf import InterfaceChoice, ServiceBrowser, ServiceListener, Zeroconf
    except ImportError:
        raise DiscoveryUnavailable("finding cars on the network needs zeroconf: pip install zeroconf "
                                   "(or add the car by its address)") from None
    if not 0 < timeout <= 30:
        raise UserError(f"the discovery time must be in (0, 30] seconds, got {timeout}")
    found: dict[str, dict[str, Any]] = {}

    class Listener(ServiceListener):
        def add_service(self, zc: Any, type_: str, name: str) -> None:
            info = zc.get_service_info(type_, name, timeout=1000)
            if info is None or not info.parsed_addresses():
                return
            host = info.parsed_addresses()[0]
            props = {k.decode(errors="replace"): (v or b"").decode(errors="replace")
                     for k, v in (info.properties or {}).items()}
            label = props.get("name") or name.removesuffix("." + type_)
            found[name] = {"name": label, "host": host, "port": info.port, "url": f"http://{host}:{info.port}/"}

        def update_service(self, zc: Any, type_: str, name: str) -> None:
            self.add_service(zc, type_, name)

        def remove_service(self, zc: Any, type_: str, name: str) -> None:
            found.pop(name, None)

    try:
        zc = Zeroconf(interfaces=interfaces or InterfaceChoice.All)
    except OSError as exc:
        logger.warning("cannot listen for cars on the network: %s", exc)
        return []
    try:
        browser = ServiceBrowser(zc, SERVICE_TYPE, Listener())
        time.sleep(timeout)
        browser.cancel()
    finally:
        zc.close()
    return sorted(found.values(), key=lambda c: (c["name"], c["url"]))
