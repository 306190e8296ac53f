"""Announcing the car on the local network (mDNS / DNS-SD, python-zeroconf), for the console to find.

The announcement says the car's name, address and web port, never its pairing token: a laptop
that finds the car still needs the token the car printed. zeroconf is optional (``pip install
zeroconf``): without it, or on a network that drops multicast, the car logs one line and the user
adds it by address.
"""

from __future__ import annotations

import logging
import socket
from typing import Any

logger = logging.getLogger(__name__)

#: the DNS-SD service type cars announce
SERVICE_TYPE = "_vehicle-car._tcp.local."


def service_label(name: str) -> str:
    """``name`` as a DNS-SD instance label (at most 63 bytes; dots would split it)."""
    return name.replace(".", "-")[:63] or "car"


class Announcer:
    """Announce ``name`` at ``host:port`` until :meth:`stop` (zeroconf runs its own threads).

    Args:
        name: the car's name (CAR_NAME).
        port: the web page's port.
        host: the bound interface; ``0.0.0.0`` announces the LAN address.
        interfaces: what zeroconf listens on (tests pass ``["127.0.0.1"]``); default every interface.
    """

    def __init__(self, name: str, port: int, host: str = "0.0.0.0", interfaces: Any = None) -> None:
        self.name, self.port, self.host, self.interfaces = name, port, host, interfaces
        self._zc: Any = None
        self._info: Any = None

    def start(self) -> Announcer:
        """Register the service; logs why not (no zeroconf, no network) and returns anyway."""
        try:
            from zeroconf import InterfaceChoice, ServiceInfo, Zeroconf
        except ImportError:
            logger.info("the car is not announced on the network (pip install zeroconf to let the console find "
                        "it); add it in the console by its address")
            return self
        from parts.web.pairing import lan_address

        address = lan_address() if self.host in ("0.0.0.0", "::", "") else self.host
        label = service_label(self.name)
        self._info = ServiceInfo(SERVICE_TYPE, f"{label}.{SERVICE_TYPE}", port=self.port,
                                 addresses=[socket.inet_aton(address)], properties={"name": self.name, "v": "1"},
                                 server=f"{label}.local.")
        try:
            self._zc = Zeroconf(interfaces=self.interfaces or InterfaceChoice.All)
            self._zc.register_service(self._info, allow_name_change=True)
        except Exception as exc:  # OSError, zeroconf's own errors (NonUniqueNameException ...) too
            logger.warning("the car could not be announced on the network (%s); add it in the console by its "
                           "address", exc)
            self.stop()
            return self
        logger.info("car announced on the network as %r (%s:%d)", self.name, address, self.port)
        return self

    def stop(self) -> None:
        """Withdraw the announcement and close zeroconf (safe to call twice)."""
        zc, self._zc = self._zc, None
        if zc is None:
            return
        try:
            if self._info is not None:
                zc.unregister_service(self._info)
        except Exception as exc:  # closing anyway
            logger.debug("zeroconf unregister: %s", exc)
        finally:
            zc.close()
