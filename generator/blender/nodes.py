"""Small builders of shader nodes shared by the materials and the sky: each adds one node to a
node tree, links its inputs (sockets or numbers) and returns its output socket."""

from __future__ import annotations


class Graph:
    """A node tree's ``nodes`` and ``links`` with one-line builders."""

    def __init__(self, nodes, links):
        self.nodes, self.links = nodes, links

    def _set(self, socket, value) -> None:
        if value is None:
            return
        if isinstance(value, (int, float)):
            socket.default_value = float(value)
        else:
            self.links.new(value, socket)

    def math(self, operation: str, a, b=None):
        """Math node ``operation`` of ``a`` and ``b``."""
        node = self.nodes.new("ShaderNodeMath")
        node.operation = operation
        for socket, value in zip(node.inputs, (a, b)):
            self._set(socket, value)
        return node.outputs[0]

    def noise(self, vector, scale: float, detail: float = 2.0, planar: bool = False):
        """Fractal noise factor (about 0.5 +- 0.2) of ``scale`` features per unit at ``vector``
        (of its x and y only when ``planar``)."""
        node = self.nodes.new("ShaderNodeTexNoise")
        node.noise_dimensions = "2D" if planar else "3D"
        node.inputs["Scale"].default_value = scale
        node.inputs["Detail"].default_value = detail
        self._set(node.inputs["Vector"], vector)
        return node.outputs["Fac"]

    def object_coordinates(self):
        """The shaded point's object coordinates (a vector socket)."""
        return self.nodes.new("ShaderNodeTexCoord").outputs["Object"]
