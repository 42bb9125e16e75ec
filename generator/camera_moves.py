"""Relative camera moves of :class:`generator.Simulator` (the paper's ``move_camera_*`` and
``turn_camera_right``), built on its public pose API: a mixin (bpy-free)."""

from __future__ import annotations

import math

from .checks import MAX_COORDINATE, check_flag, check_number
from .geometry import camera as cam_model


class CameraMoves:
    """Moves along the camera's own axes and turns about the world vertical; each goes
    through ``set_world_from_camera`` (so with its collision check) and returns True if
    the move was refused."""

    def _move(self, axis: int, distance: float) -> bool:
        d = check_number("distance", distance)
        target = cam_model.translated_along_axis(self.get_world_from_camera(), axis, d)
        if abs(target[:3, 3]).max() > MAX_COORDINATE:
            raise ValueError(f"distance {d:g} m would take the camera farther than {MAX_COORDINATE:.0e} m "
                             "from the origin")
        return self.set_world_from_camera(target)

    def move_camera_forward(self, distance: float) -> bool:
        """Move along the optical axis (camera +z) by ``distance`` metres; True if refused."""
        return self._move(2, distance)

    def move_camera_right(self, distance: float) -> bool:
        """Move along camera +x by ``distance`` metres; True if refused."""
        return self._move(0, distance)

    def move_camera_down(self, distance: float) -> bool:
        """Move along camera +y (image down) by ``distance`` metres; True if refused."""
        return self._move(1, distance)

    def turn_camera_right(self, angle: float, degrees: bool = True) -> bool:
        """Turn right (clockwise seen from above) about the world Z axis through the camera
        centre; the horizon stays level. Never collides (returns False)."""
        a = check_number("angle", angle)
        # whole turns first (exact: fmod), so that any finite angle turns as its remainder
        a = math.radians(math.fmod(a, 360.0)) if check_flag("degrees", degrees) else math.fmod(a, 2 * math.pi)
        return self.set_world_from_camera(cam_model.turned_about_world_z(self.get_world_from_camera(), a), check_collisions=False)
