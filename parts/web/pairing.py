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
import math
import secrets
import socket
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable

from vehicle.config_checks import secret_bits

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


#: estimated bits a user's WEB_TOKEN must reach (a random one has 96; WEB_TOKEN's declaration says the same)
MIN_TOKEN_BITS = 64
#: wrong tokens a client may send before it must wait
FREE_FAILURES = 5
#: the first wait after the free failures, seconds; it doubles with each further failure
FIRST_LOCKOUT_S = 1.0
#: the longest wait, seconds (a guesser gets at most one try a minute)
MAX_LOCKOUT_S = 60.0
#: clients remembered (the oldest is forgotten first): memory stays bounded under a flood
MAX_CLIENTS = 1024
#: seconds between two log lines about the same client's failures
LOG_EVERY_S = 60.0


def token_weakness(token: str) -> str | None:
    """Why ``token`` is too weak to guard a car on a network (None when it is strong enough)."""
    bits = secret_bits(token)
    if bits >= MIN_TOKEN_BITS:
        return None
    return (f"is too weak: about {bits:.0f} bits, at least {MIN_TOKEN_BITS} needed (e.g. 16 random letters "
            "and digits; repeated characters and a single kind of character count little)")


def resolve_token(host: str, token: str | None) -> str | None:
    """The token connections must present: the configured one, else a fresh random one when
    ``host`` is not loopback, else None (no token needed on localhost). ValueError for a token
    too short or too weak to be guessed slowly."""
    if token is not None:
        if len(token) < 8:
            raise ValueError("WEB_TOKEN must be at least 8 characters (or None for a random one "
                             "when the page is reachable from the network)")
        weak = token_weakness(token)
        if weak is not None:
            raise ValueError(f"WEB_TOKEN ({len(token)} characters) {weak}; or None for a random one")
        return token
    if is_loopback(host):
        return None
    return secrets.token_urlsafe(12)


class FailureGuard:
    """Slows a client that sends wrong pairing tokens: after :data:`FREE_FAILURES` its wrong tokens
    must wait (1 s, then twice as long after each further failure, up to :data:`MAX_LOCKOUT_S`).
    The right token is never made to wait: a client is an address, and a guesser behind the same
    NAT as the driver must not keep the driver out. Failures are logged once per client per
    :data:`LOG_EVERY_S`.

    Args:
        server: the name logs give the server (``console``, ``web``).
        clock: monotonic seconds (tests pass their own).
    """

    def __init__(self, server: str, clock: Callable[[], float] = time.monotonic) -> None:
        self.server = server
        self._clock = clock
        # client -> [failures, locked until, last logged, failures since the last log line]
        self._clients: OrderedDict[str, list[float]] = OrderedDict()

    def __len__(self) -> int:
        return len(self._clients)

    def wait_s(self, client: str) -> float:
        """Seconds ``client`` must wait before its token is checked again (0: check it now)."""
        entry = self._clients.get(client)
        return 0.0 if entry is None else max(0.0, entry[1] - self._clock())

    def refusal_s(self, client: str, right: bool) -> int:
        """Whole seconds (the Retry-After) ``client`` must wait before a token that is not
        ``right`` is answered; 0: answer now. The right token never waits."""
        wait = 0.0 if right else self.wait_s(client)
        return max(1, math.ceil(wait)) if wait > 0 else 0

    def failed(self, client: str) -> None:
        """Count a wrong token from ``client``."""
        now = self._clock()
        entry = self._clients.pop(client, None) or [0, 0.0, -math.inf, 0]
        self._clients[client] = entry  # most recent last: the oldest is forgotten first
        while len(self._clients) > MAX_CLIENTS:
            self._clients.popitem(last=False)
        entry[0] += 1
        entry[3] += 1
        over = entry[0] - FREE_FAILURES
        if over >= 0:
            entry[1] = now + min(MAX_LOCKOUT_S, FIRST_LOCKOUT_S * 2.0 ** min(over, 16))
        if now - entry[2] >= LOG_EVERY_S:
            logger.warning("%s: %d wrong pairing token%s from %s (%d in all); %s", self.server, entry[3],
                           "" if entry[3] == 1 else "s", client, entry[0],
                           f"it waits {entry[1] - now:.0f} s before its next try" if over >= 0
                           else "a guesser is slowed after a few")
            entry[2], entry[3] = now, 0

    def succeeded(self, client: str) -> None:
        """Forget ``client``'s failures (it paired)."""
        self._clients.pop(client, None)


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
