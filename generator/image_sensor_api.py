"""``Simulator.set_image_sensor``: exposure, sensor noise and JPEG on the display colour, on
the Simulator's public API (a mixin, bpy-free; docs/cameras.md, "Exposure and noise").

The sensor works on the display image Blender renders (generator/image_sensor.py); the
scene-linear colour and every ground truth stay as rendered and cast.
"""

from __future__ import annotations

from .image_sensor import IDEAL, ImageSensor, image_sensor_of, view_stream


class ImageSensors:
    """Adds :meth:`set_image_sensor` and :attr:`image_sensor` to the Simulator."""

    image_sensor: ImageSensor = IDEAL

    def set_image_sensor(self, exposure="as-rendered", full_well_e=None, read_noise_e=0.0,
                         jpeg_quality=None) -> ImageSensor:
        """What the camera's sensor does to ``render()``'s ``rgb`` from now on: ``exposure``
        ``"as-rendered"`` (0 stops), a number of stops (-10 to 10) or ``"auto"`` (average
        metering to mid-grey); ``full_well_e`` electrons at saturation with ``read_noise_e``
        electrons of read noise (None: no noise); ``jpeg_quality`` 1-100 (None: no JPEG).
        ``render().exposure_gain`` says the gain applied. Refused in one line when a value is
        out of range. Returns the sensor."""
        if isinstance(exposure, bool):
            raise ValueError(f"exposure must be 'auto', 'as-rendered' or a number of stops, got {exposure!r}")
        if full_well_e is None and read_noise_e:
            raise ValueError("read noise needs a full well (electrons at saturation) to be measured against")
        self.image_sensor = image_sensor_of(exposure, () if full_well_e is None else (full_well_e, read_noise_e),
                                            jpeg_quality)
        return self.image_sensor

    def _sense(self, out):
        """``out`` (a RenderOutput) with its display colour as the image sensor gives it."""
        if self.image_sensor.ideal or out.rgb is None:
            return out
        rng = None if self.image_sensor.full_well_e is None else view_stream(self.seed, out.frame,
                                                                            out.world_from_camera)
        out.rgb, out.exposure_gain = self.image_sensor.apply(out.rgb, rng)
        return out
