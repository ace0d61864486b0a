"""``render_mode="rgb_array"``: one RGB frame of the last seconds of an episode.

The frame shows what the stick-slip and whirl metrics read: the bit and surface speeds
and the torque on bit over the last ``seconds`` (left), and the orbit of the bit centre
inside its gauge clearance (right, the circle is the wall). It is drawn with Pillow
(a Matplotlib dependency) into an array in about a millisecond, with no display, so
Gymnasium's ``RecordVideo``/``RenderCollection`` and SB3's ``make_vec_env`` (which asks
for ``rgb_array``) work. For full episodes with every channel, use the rerun recording
(:mod:`drill_env.recording`).
"""

from __future__ import annotations

import math

import numpy as np

from drill_env.physics.units import RPM

#: Colours (RGB) of the traces.
BIT = (31, 119, 180)
SURFACE = (255, 127, 14)
TORQUE = (44, 160, 44)
WALL = (120, 120, 120)
ORBIT = (214, 39, 40)
BACKGROUND = (255, 255, 255)
INK = (40, 40, 40)


class FrameHistory:
    """A ring buffer of the record rows the frame plots (the last ``capacity`` rows)."""

    def __init__(self, channels: tuple[str, ...], capacity: int) -> None:
        self.columns = {name: channels.index(name) for name in
                        ("time", "bit_speed", "surface_speed", "torque_on_bit", "bit_x", "bit_y")}
        self.capacity = max(2, int(capacity))
        self._rows = np.zeros((self.capacity, len(channels)))
        self._size = 0
        self._next = 0

    def clear(self) -> None:
        self._size = 0
        self._next = 0

    def add(self, records: np.ndarray) -> None:
        for row in records[-self.capacity:]:
            if not np.all(np.isfinite(row)):
                continue
            self._rows[self._next] = row
            self._next = (self._next + 1) % self.capacity
            self._size = min(self._size + 1, self.capacity)

    def column(self, name: str) -> np.ndarray:
        """The channel ``name`` in time order."""
        order = (np.arange(self._size) + self._next - self._size) % self.capacity
        return self._rows[order, self.columns[name]]

    def __len__(self) -> int:
        return self._size


def _polyline(x: np.ndarray, y: np.ndarray, box: tuple[int, int, int, int],
              x_range: tuple[float, float], y_range: tuple[float, float]) -> list[tuple]:
    """Data points mapped into the pixel box (left, top, right, bottom)."""
    left, top, right, bottom = box
    x0, x1 = x_range
    y0, y1 = y_range
    px = left + (x - x0) / max(x1 - x0, 1e-12) * (right - left)
    py = bottom - (np.clip(y, y0, y1) - y0) / max(y1 - y0, 1e-12) * (bottom - top)
    return list(zip(px.tolist(), py.tolist(), strict=True))


def _nice_ceiling(value: float) -> float:
    """The smallest 1, 2 or 5 x 10^k at or above ``value``."""
    if not value > 0 or not math.isfinite(value):
        return 1.0
    exponent = math.floor(math.log10(value))
    for step in (1.0, 2.0, 5.0, 10.0):
        if step * 10.0**exponent >= value:
            return step * 10.0**exponent
    return 10.0 ** (exponent + 1)


def draw_frame(history: FrameHistory, clearance: float, speed_max: float,
               width: int = 640, height: int = 360, title: str = "") -> np.ndarray:
    """The frame as a ``(height, width, 3)`` uint8 array."""
    from PIL import Image, ImageDraw

    image = Image.new("RGB", (width, height), BACKGROUND)
    draw = ImageDraw.Draw(image)
    split = int(width * 0.62)
    speed_box = (46, 22, split - 10, height // 2 - 12)
    torque_box = (46, height // 2 + 14, split - 10, height - 22)
    for box in (speed_box, torque_box):
        draw.rectangle(box, outline=INK)
    draw.text((4, 4), title, fill=INK)
    if len(history) >= 2:
        t = history.column("time")
        t_range = (float(t[0]), float(max(t[-1], t[0] + 1e-6)))
        bit = history.column("bit_speed") / RPM
        surface = history.column("surface_speed") / RPM
        top = _nice_ceiling(max(float(np.max(bit)), float(np.max(surface)), speed_max / RPM * 0.5))
        # a backward turn of the bit widens the axis; round-off below zero does not (it
        # printed "-0")
        bottom = min(0.0, -_nice_ceiling(-float(np.min(bit)))) if np.min(bit) < -0.5 else 0.0
        draw.line(_polyline(t, surface, speed_box, t_range, (bottom, top)), fill=SURFACE, width=1)
        draw.line(_polyline(t, bit, speed_box, t_range, (bottom, top)), fill=BIT, width=2)
        draw.text((4, speed_box[1]), f"{top:.0f}", fill=INK)
        draw.text((4, speed_box[3] - 10), f"{bottom:.0f}", fill=INK)
        draw.text((speed_box[0] + 4, speed_box[1] + 2), "rpm: bit (blue), surface (orange)",
                  fill=INK)
        torque = history.column("torque_on_bit") / 1e3
        t_top = _nice_ceiling(float(np.max(np.abs(torque))))
        t_low = -t_top if np.min(torque) < 0 else 0.0
        draw.line(_polyline(t, torque, torque_box, t_range, (t_low, t_top)), fill=TORQUE,
                  width=2)
        draw.text((4, torque_box[1]), f"{t_top:.0f}", fill=INK)
        draw.text((4, torque_box[3] - 10), f"{t_low + 0.0:.0f}", fill=INK)
        draw.text((torque_box[0] + 4, torque_box[1] + 2), "torque on bit (kN m)", fill=INK)
        draw.text((torque_box[0], height - 16), f"t = {t_range[0]:.1f} ... {t_range[1]:.1f} s",
                  fill=INK)
    # orbit: the wall is the clearance circle, the bit centre's trail inside it
    size = min(width - split - 20, height - 60)
    cx, cy = split + (width - split) // 2, height // 2
    r_px = size / 2
    draw.ellipse((cx - r_px, cy - r_px, cx + r_px, cy + r_px), outline=WALL, width=2)
    draw.line([(cx - 3, cy), (cx + 3, cy)], fill=WALL)
    draw.line([(cx, cy - 3), (cx, cy + 3)], fill=WALL)
    draw.text((split + 4, 22), "bit orbit in the clearance", fill=INK)
    if len(history) >= 2:
        x = history.column("bit_x") / clearance
        y = history.column("bit_y") / clearance
        scale = np.maximum(1.0, np.hypot(x, y))  # beyond the wall: drawn on it
        points = list(zip((cx + r_px * x / scale).tolist(), (cy - r_px * y / scale).tolist(),
                          strict=True))
        draw.line(points, fill=ORBIT, width=1)
        px, py = points[-1]
        draw.ellipse((px - 3, py - 3, px + 3, py + 3), fill=ORBIT)
        draw.text((split + 4, height - 16), f"r / clearance = {math.hypot(x[-1], y[-1]):.2f}",
                  fill=INK)
    return np.asarray(image, dtype=np.uint8)
