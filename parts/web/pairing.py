"""Who may talk to the car: the pairing token and the host names the page may be opened by.

The token travels in the page URL (``http://car:8887/?token=...``); the page passes it in the
Socket.IO handshake and the server refuses any connection without it. The URL is logged at start
and, when the optional ``qrcode`` package is installed, drawn as a QR code in the terminal so a
phone can scan it.

Host names: on loopback no token is needed, so a page of another site must never reach the
server. A site whose name an attacker makes resolve to 127.0.0.1 (DNS rebinding) is same-origin
with itself, so the Origin check alone lets it in; the ``Host`` header it sends still names the
attacker's domain. The server therefore answers only requests whose Host is an IP address (which
cannot be rebound), ``localhost``, this machine's name, the configured host or a name the user
allowed (:func:`allowed_hosts`, :func:`host_allowed`).
"""

from __future__ import annotations

import hmac
import ipaddress
import logging
import secrets
import socket
from collections.abc import Iterable

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


#: names that always mean this machine
LOOPBACK_NAMES = frozenset({"localhost", "ip6-localhost", "ip6-loopback"})


def allowed_hosts(host: str, extra: Iterable[str] = ()) -> frozenset[str]:
    """Host names (lower case) a request may carry besides IP addresses: ``localhost``, the bound
    ``host`` when it is a name, this machine's name (and ``NAME.local``, its mDNS name) when the
    server listens on the network, and ``extra`` (WEB_ALLOWED_HOSTS)."""
    names = set(LOOPBACK_NAMES)
    bound = host.strip("[]").lower().rstrip(".")
    if bound and bound not in ("0.0.0.0", "::") and not _is_ip(bound):
        names.add(bound)
    if not is_loopback(host):
        machine = socket.gethostname().lower().rstrip(".")
        if machine:
            names.update({machine, f"{machine.split('.')[0]}.local"})
    names.update(n.strip().lower().rstrip(".") for n in extra if n.strip())
    return frozenset(names)


def host_allowed(host_header: str | None, allowed: frozenset[str]) -> bool:
    """Whether a request's ``Host`` header (``name[:port]``, ``[v6]:port``) names this car: an IP
    address, or a name in ``allowed``."""
    if not host_header:
        return False
    text = host_header.strip().lower()
    if text.startswith("["):  # [v6 literal]:port
        end = text.find("]")
        return end > 0 and _is_ip(text[1:end])
    name = text.rsplit(":", 1)[0] if text.count(":") == 1 else text
    name = name.rstrip(".")
    return _is_ip(name) or name in allowed


def _is_ip(text: str) -> bool:
    try:
        ipaddress.ip_address(text)
    except ValueError:
        return False
    return True


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
