"""Settings of the web controller page.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated, Literal

from vehicle.config_checks import Length, Range

# == Web controller ==

# Serve the web controller page (camera view, joystick, keyboard, modes, recording, e-stop). With
# USE_JOYSTICK_AS_DEFAULT both drive, arbitrated by CONTROLLER_PRIORITY.
USE_WEB_CONTROLLER: bool = True
# TCP port of the page (DonkeyCar's name and default): http://localhost:8887/
WEB_CONTROL_PORT: Annotated[int, Range(0, 65535, note="0 picks a free port")] = 8887
# Interface the page listens on. "127.0.0.1" = this machine only; "0.0.0.0" = every network
# interface (a phone on the car's Wi-Fi), which then requires the pairing token.
WEB_HOST: str = "127.0.0.1"
# Pairing token browsers must present (in the page URL, ?token=...). None: none on localhost, a
# random one per start when WEB_HOST is a network interface (printed with the URL at start).
# At least 8 characters and hard to guess (about 64 bits: 16 random letters and digits; 8 digits
# are refused); when set it is required even on localhost. Wrong tokens are slowed per client.
WEB_TOKEN: Annotated[str | None, Length(min=8, secret=True, min_bits=64,
                                        note="or None: a random token when the page is on the network")] = None
# More host names the page may be opened by, e.g. ["mycar.example.org"] for a DNS name of the car
# or a reverse proxy. IP addresses, localhost, this machine's name (and NAME.local) and WEB_HOST
# are always accepted; a request naming any other host is refused, so that a web site made to
# resolve to the car (DNS rebinding) cannot reach it.
WEB_ALLOWED_HOSTS: list[str] = []
# Dead-man time in seconds: when the driving page sends no control message for this long while
# the throttle is non-zero (or a pilot mode is on), throttle goes to 0 and the mode to user.
WEB_DEADMAN_S: Annotated[float, Range(0.1, 2, unit="s")] = 0.5
# Initial maximum throttle of the page, [0, 1]: the page's full stick gives this throttle; it can be
# changed on the page and is also the constant-throttle value.
WEB_MAX_THROTTLE: Annotated[float, Range(0, 1)] = 0.5
# Largest speed limit the page's slider offers, m/s (sent as user/speed_limit: the car's speed is
# capped at it in every mode; it needs a measured speed, the simulator's or an encoder's).
WEB_MAX_SPEED_LIMIT: Annotated[float, Range(0, 100, lo_open=True, unit="m/s")] = 5.0
# State updates (gauges, counts, loop health) sent to each page per second.
WEB_TELEMETRY_HZ: Annotated[float, Range(0, 100, lo_open=True, unit="Hz")] = 20.0
# JPEG quality of the camera view, 1-100 (80: ~3 KB for a 160x120 frame).
WEB_JPEG_QUALITY: Annotated[int, Range(1, 100)] = 80
# Who drives when both the web page and the gamepad give commands: "gamepad" (the gamepad whenever
# its stick is off centre), "web" (the page whenever its command is off centre) or "latest" (the
# source that moved last). Mode and recording: the latest change from either wins; an emergency
# stop from either holds.
CONTROLLER_PRIORITY: Literal["gamepad", "web", "latest"] = "gamepad"

# == Laptop link ==

# Let the paired laptop (`vehicle car ...`, the trainer console's Cars page) list and pull this car's
# tubs, push model files and switch the pilot, over the web page's server with its pairing token.
CAR_LINK: bool = True
# Largest model file the laptop may push, MB (a linear pilot is about 1 MB).
CAR_MAX_MODEL_MB: Annotated[float, Range(0, 4000, lo_open=True, unit="MB")] = 200.0
# Announce the car on the local network (mDNS/zeroconf, `pip install zeroconf`) so the console finds
# it; only when WEB_HOST is a network interface. The pairing token is never announced.
CAR_ANNOUNCE: bool = True
# The car's name in the console and on the network. None: the car folder's name.
CAR_NAME: Annotated[str | None, Length(min=1, max=63)] = None
