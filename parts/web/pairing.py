"""Pairing: when the page is reachable from the network, every browser needs the car's token.

The token travels in the page URL (``http://car:8887/?token=...``); the page passes it in the
Socket.IO handshake and the server refuses any connection without it. The URL is logged at start
and, when the optional ``qrcode`` package is installed, drawn as a QR code in the terminal so a
phone can scan it.
"""

from __future__ import annotations

import hmac
import ipaddress
import logging
import secrets
import socket

logger = logging.getLogger(__name__)


def is_loopback(host: str) -> bool:
    """Whether binding to ``host`` keeps the server reachable from this machine only."""
    if host in ("localhost", "ip6-localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:  # a host name: resolve it without touching the network
        try:
            infos = socket.getaddrinfo(host, None, proto=socket.IPPROTO_TCP)
        except OSError:
            return False
        return bool(infos) and all(ipaddress.ip_address(i[4][0]).is_loopback for i in infos)


def resolve_token(host: str, token: str | None) -> str | None:
    """The token connections must present: the configured one, else a fresh random one when
    ``host`` is not loopback, else None (no token needed on localhost)."""
    if token is not None:
        if len(token) < 8:
            raise ValueError("WEB_TOKEN must be at least 8 characters (or None for a random one "
                             "when the page is reachable from the network)")
        return token
    if is_loopback(host):
        return None
    return secrets.token_urlsafe(12)


def token_ok(expected: str | None, auth: object) -> bool:
    """Whether a Socket.IO handshake ``auth`` payload carries the expected token."""
    if expected is None:
        return True
    given = auth.get("token") if isinstance(auth, dict) else None
    if not isinstance(given, str):
        return False
    return hmac.compare_digest(given.encode(), expected.encode())


def lan_address() -> str:
    """This machine's address on the local network (for the URL a phone opens)."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        # connect() on UDP only picks the outgoing interface; no packet is sent
        probe.connect(("10.255.255.255", 1))
        return probe.getsockname()[0]
    except OSError:
        return socket.gethostname()
    finally:
        probe.close()


def page_url(host: str, port: int, token: str | None) -> str:
    """The URL of the page for a browser: the LAN address when bound to every interface."""
    shown = lan_address() if host in ("0.0.0.0", "::", "") else host
    if ":" in shown:  # IPv6 literal
        shown = f"[{shown}]"
    url = f"http://{shown}:{port}/"
    return f"{url}?token={token}" if token else url


def terminal_qr(text: str) -> str | None:
    """``text`` as a QR code drawn with text blocks, or None if ``qrcode`` is not installed."""
    try:
        import qrcode
    except ImportError:
        return None
    qr = qrcode.QRCode(border=1)
    qr.add_data(text)
    qr.make(fit=True)
    rows = qr.get_matrix()
    # two modules per character row; light modules are drawn (terminals are dark), so a dark
    # module is a space: (upper light, lower light) -> full block, upper half, lower half, space
    chars = {(True, True): "\u2588", (True, False): "\u2580", (False, True): "\u2584",
             (False, False): " "}
    lines = []
    for y in range(0, len(rows), 2):
        lower = rows[y + 1] if y + 1 < len(rows) else [False] * len(rows[y])
        lines.append("".join(chars[(not a, not b)] for a, b in zip(rows[y], lower, strict=True)))
    return "\n".join(lines)
