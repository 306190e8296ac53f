"""Settings of recording: tubs, their keys and durability.

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Annotated, Any

from parts.tub.format import ALL_TYPES
from vehicle.config_checks import Length, OneOf, Problem, Range, Rule

# == Recording ==

# Start a new tub folder DATA_PATH/tub_<N>_<YY-MM-DD> at each drive (True), or append every drive
# to the one tub DATA_PATH (False, DonkeyCar's default). One tub per drive makes a bad drive easy
# to throw away; training reads a tub or a folder of tubs either way.
AUTO_CREATE_NEW_TUB: bool = True
# Memory keys recorded into the tub, each with its tub type in TUB_TYPES. With RECORD_DURING_AI,
# pilot/angle and pilot/throttle are added. The camera's cam/timestamp, when some part produces
# it, becomes each record's _timestamp_ms.
TUB_INPUTS: Annotated[list[str], Length(min=1)] = ["cam/image_array", "user/angle", "user/throttle", "user/mode"]
# Tub type of each TUB_INPUTS key, in the same order (how it is stored: docs/data-format.md).
TUB_TYPES: Annotated[list[str], OneOf(ALL_TYPES)] = ["image_array", "float", "float", "str"]
# User metadata stored in the tub's manifest, "key:value" items (DonkeyCar's --meta), e.g.
# ["driver:ann", "track:garage"].
METADATA: list[str] = []
# Records per catalog file (DonkeyCar's max_catalog_len).
TUB_MAX_CATALOG_LEN: Annotated[int, Range(1)] = 1000
# Durability window: records are made durable (images synced to the disk, then their catalog
# lines appended and fsynced, then the manifest replaced atomically) every TUB_FSYNC_RECORDS records or when the
# oldest unsaved record is TUB_FSYNC_MS milliseconds old, whichever comes first. While recording, a
# crash loses at most two windows and a power cut three, plus the records still queued (see
# TUB_QUEUE_SIZE and docs/data-format.md).
TUB_FSYNC_RECORDS: Annotated[int, Range(0, note="0 commits every record")] = 20
# Age in milliseconds of the oldest unsaved record that triggers a commit (see TUB_FSYNC_RECORDS).
TUB_FSYNC_MS: Annotated[int, Range(0, unit="ms")] = 500
# fsync at each commit (protects against power loss). False: commits still happen per window, but
# only a crash of the process (not a power cut) is survived; faster on slow SD cards.
TUB_FSYNC: bool = True
# Records in flight to the recording thread (accepted, not yet written); beyond it new records are
# dropped, counted and a warning is logged (the loop never waits for the disk). 100 = 5 s at 20 Hz.
TUB_QUEUE_SIZE: Annotated[int, Range(1)] = 100
# JPEG quality of recorded images, 1-100. 75 is DonkeyCar's (PIL's default): ~3-5 KB per 160x120
# frame.
TUB_JPEG_QUALITY: Annotated[int, Range(1, 100)] = 75


def _tub_schema(v: Mapping[str, Any]) -> Iterator[Problem]:
    inputs, types = v["TUB_INPUTS"], v["TUB_TYPES"]
    if len(inputs) != len(types):
        yield Problem("TUB_TYPES", f"TUB_TYPES = {types!r} has {len(types)} types for {len(inputs)} "
                      "TUB_INPUTS; valid: one type per TUB_INPUTS key, in the same order",
                      ("TUB_INPUTS",))


#: rules across this module's settings, run after every setting passed its own range
RULES: tuple[Rule, ...] = (_tub_schema,)
