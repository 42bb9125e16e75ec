"""``Simulator.set_lens``: the camera's lens model, on the Simulator's public API (a mixin;
docs/cameras.md).

The lens bends the rays of both the colour render (a Cycles custom camera:
generator/blender/lens_camera.py) and the ground truth (one ray per pixel centre through the
same model, in float64: generator/geometry/raycam.py), so depth, labels, instance ids,
normals and flow stay exact, pixel for pixel, under distortion. ``project`` and
``depth_to_world_points`` go through it, and ``compute_point_cloud`` counts a point in view
when it projects into the image through it.
"""

from __future__ import annotations

from .geometry.lens import PINHOLE, Lens


class Lenses:
    """Adds :meth:`set_lens` and :attr:`lens` to the Simulator."""

    lens: Lens = PINHOLE

    def set_lens(self, model: str = "pinhole", coefficients=()) -> Lens:
        """Render and compute the ground truth through a lens model: ``"pinhole"`` (no
        coefficients), ``"opencv"`` (k1, k2, p1, p2[, k3]: OpenCV's radial-tangential model) or
        ``"fisheye"`` (k1, k2, k3, k4: OpenCV's equidistant fisheye). ``K`` keeps its meaning
        (focal lengths and principal point, pixels). Refused in one line when the model folds
        back inside the image (generator/geometry/lens.py). Returns the lens."""
        self._check_current()
        lens = Lens(model, tuple(coefficients))
        self._apply_lens(lens)
        return lens

    def _apply_lens(self, lens: Lens) -> None:
        from .blender.lens_camera import apply_lens

        lens.check(self.K, self.width, self.height)
        apply_lens(self._camera, lens, self.K, self.width, self.height)
        self.lens = lens
