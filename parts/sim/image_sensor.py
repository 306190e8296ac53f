"""The simulated camera's image sensor and pipeline: what they do to every frame (motion blur, lens
vignetting, brightness jitter, noise, blur and JPEG compression).

These are the only per-frame costs of randomisation, so each is one or two OpenCV calls on the
uint8 image: noise comes from a bank of noise frames drawn once per episode (a random window of
it each frame), vignetting is one multiply by a precomputed gain map, motion blur a vertical box
filter whose length follows the car's speed, JPEG a real encode/decode at the episode's quality.
"""

from __future__ import annotations

import cv2
import numpy as np

#: noise frames in the bank (each frame uses a random window of one of them)
_BANK = 6
#: extra rows/columns of each bank frame, so that windows at different offsets differ
_PAD = 16
#: image motion of the ground near the bottom of a 120-row frame per m/s of speed, rows per second
#: (a camera 0.2 m high pitched 20 deg down sees the ground there move at ~4 rows per cm)
_FLOW_ROWS_PER_M = 450.0


class ImageSensor:
    """Per-frame image effects (all off by default; seeded, so a run is reproducible).

    Args:
        width, height: image size, pixels.
        noise: standard deviation of per-pixel noise, 0-255 units.
        blur: box-blur kernel size in pixels (0 or 1 = off).
        brightness: each frame is scaled by a factor drawn from [1 - b, 1 + b].
        vignetting: darkening of the corners, fraction (0.3 = corners at 70 %).
        motion_blur: exposure time in seconds; the blur length follows the speed passed to apply().
        jpeg_quality: compress every frame as JPEG at this quality (1-100), None = off.
        seed: seed of the per-frame draws.
    """

    def __init__(self, width: int, height: int, *, noise: float = 0.0, blur: int = 0, brightness: float = 0.0,
                 vignetting: float = 0.0, motion_blur: float = 0.0, jpeg_quality: int | None = None,
                 seed: int | tuple[int, ...] = 0) -> None:
        if noise < 0 or blur < 0 or not 0 <= brightness < 1:
            raise ValueError(f"image jitter out of range (noise {noise} >= 0, blur {blur} >= 0, "
                             f"0 <= brightness {brightness} < 1)")
        if not 0 <= vignetting < 1 or motion_blur < 0:
            raise ValueError(f"sensor effects out of range (0 <= vignetting {vignetting} < 1, "
                             f"motion blur {motion_blur} >= 0 s)")
        if jpeg_quality is not None and not 1 <= jpeg_quality <= 100:
            raise ValueError(f"JPEG quality {jpeg_quality} out of range: use 1 .. 100")
        self.width, self.height = int(width), int(height)
        self.noise, self.blur, self.brightness = float(noise), int(blur), float(brightness)
        self.vignetting, self.motion_blur = float(vignetting), float(motion_blur)
        self.jpeg_quality = None if jpeg_quality is None else int(jpeg_quality)
        seeds = [s & 0xFFFFFFFF for s in (seed if isinstance(seed, tuple) else (seed,))]
        self.rng = np.random.default_rng([*seeds, 0x1A7])
        self._bank: list[tuple[np.ndarray, np.ndarray]] = []
        self._gain: np.ndarray | None = None
        if self.noise > 0:
            for _ in range(_BANK):
                n = self.rng.standard_normal((self.height + _PAD, self.width + _PAD, 3), dtype=np.float32)
                n *= self.noise
                np.clip(n, -255, 255, out=n)
                # uint8 saturating add of the positive part, subtract of the negative part
                self._bank.append((np.maximum(n, 0).astype(np.uint8), np.maximum(-n, 0).astype(np.uint8)))
        if self.vignetting > 0:
            ys, xs = np.mgrid[0:self.height, 0:self.width].astype(np.float32)
            half = self.width / 2  # the same scale both ways: a round lens
            r2 = ((xs - (self.width - 1) / 2) / half) ** 2 + ((ys - (self.height - 1) / 2) / half) ** 2
            r2 /= r2.max()  # 1 in the corners
            gain = 1.0 - self.vignetting * r2 ** 1.5
            self._gain = np.repeat((gain * 255.0 + 0.5).astype(np.uint8)[..., None], 3, axis=2)

    @property
    def active(self) -> bool:
        """Whether any effect is on."""
        return (self.noise > 0 or self.blur > 1 or self.brightness > 0 or self.vignetting > 0
                or self.motion_blur > 0 or self.jpeg_quality is not None)

    def apply(self, image: np.ndarray, speed: float = 0.0) -> np.ndarray:
        """Apply the effects to ``image`` (HxWx3 uint8) in place and return it; ``speed`` in m/s."""
        if self.motion_blur > 0 and speed != 0.0:
            # forward motion smears the ground vertically, most at the bottom of the frame
            rows = abs(speed) * self.motion_blur * _FLOW_ROWS_PER_M * self.height / 120.0
            h = self.height
            for top, share in ((h // 2, 0.35), (3 * h // 4, 0.7), (7 * h // 8, 1.0)):
                k = int(round(rows * share))
                if k >= 2:
                    band = image[top:]
                    cv2.blur(band, (1, k), dst=band)
        if self.blur > 1:
            cv2.blur(image, (self.blur, self.blur), dst=image)
        if self._gain is not None:
            cv2.multiply(image, self._gain, dst=image, scale=1.0 / 255.0)
        if self.brightness > 0:
            factor = self.rng.uniform(1 - self.brightness, 1 + self.brightness)
            cv2.convertScaleAbs(image, dst=image, alpha=factor)
        if self._bank:
            pos, neg = self._bank[int(self.rng.integers(_BANK))]
            oy, ox = (int(v) for v in self.rng.integers(0, _PAD + 1, 2))
            cv2.add(image, pos[oy:oy + self.height, ox:ox + self.width], dst=image)
            cv2.subtract(image, neg[oy:oy + self.height, ox:ox + self.width], dst=image)
        if self.jpeg_quality is not None:
            ok, data = cv2.imencode(".jpg", cv2.cvtColor(image, cv2.COLOR_RGB2BGR),
                                    (cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality))
            if ok:
                cv2.cvtColor(cv2.imdecode(data, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB, dst=image)
        return image
