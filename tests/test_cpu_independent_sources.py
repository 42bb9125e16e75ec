"""No maths whose rounding depends on the CPU in the code that makes a seed's bytes.

numpy's ``@``, ``dot`` and 1-D ``linalg.norm`` go to BLAS, ``linalg.inv``/``svd``/``det`` to
LAPACK, its ``sin``, ``arctan2``, ``exp``, ``power`` (``x ** 3``) ... to loops or C-library
functions picked by CPU, and so do Python's ``math.sin`` ... (docs/guarantees.md, "Same
bytes"; tests/test_same_bytes.py shows each one changing under stand-in CPUs). The
generator, the trajectories and the exporters use ``generator/geometry/portable_math.py``,
``camera.matmul_exact``/``rows_times``/``apply_affine``/``affine_inverse``/``polar_factor`` and
``nearest_rotation`` instead. This test reads their sources (Python's ``ast``) and fails on
any such call that is not in ALLOWED below, each with the reason it cannot change a byte.
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("generator", "trajectories", "exporters")
NUMPY_DISPATCHED = {"sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh", "exp",
                    "exp2", "expm1", "log", "log1p", "log2", "log10", "power", "float_power", "cbrt", "hypot"}
NUMPY_BLAS = {"dot", "matmul", "inner", "vdot", "tensordot", "outer"}
MATH_DISPATCHED = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "exp2",
                   "expm1", "log", "log1p", "log2", "log10", "pow", "hypot", "dist", "cbrt"}
EXACT_POWERS = (2, 0.5, 1, -1)  # numpy turns these into a square, a square root, a copy, a reciprocal

# (file, expression): why it cannot change a byte of a seed's output
ALLOWED = {
    ("generator/blender/extract.py", "np.linalg.det(world[:3, :3])"): "only its sign (a mirrored object)",
    ("generator/geometry/boxes.py", "(planes < 0).astype(np.uint8) @ np.array([1, 2, 4, 8, 16], np.uint8)"):
        "integers",
    ("generator/geometry/camera.py", "out @ CV_FROM_BLENDER_CAMERA"): "a signed permutation: every sum has one term",
    ("generator/geometry/camera.py", "np.asarray(world_from_camera, dtype=np.float64) @ CV_FROM_BLENDER_CAMERA"):
        "a signed permutation: every sum has one term",
    ("exporters/nerfstudio.py", "np.asarray(world_from_camera, np.float64) @ OPENCV_TO_OPENGL"):
        "a signed permutation: every sum has one term",
    ("generator/geometry/camera.py", "r.T @ r"): "a check against a tolerance of user input",
    ("generator/geometry/camera.py", "np.linalg.det(r)"): "a check of user input (its sign)",
    ("exporters/colmap.py", "r.T @ r"): "a check of a file being read, against a tolerance",
    ("exporters/colmap.py", "np.linalg.det(r)"): "a check of a file being read, against a tolerance",
    ("generator/geometry/point_blocks.py", "self.a @ c"):
        "settles whole groups of points only with a margin; the answer is the per-point rule's "
        "(tests/test_visibility.py: the same bits as testing every point)",
    ("generator/geometry/point_blocks.py", "self.abs_a @ np.abs(c)"): "the margin of the line above",
}


def _is_int_constant(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and type(node.value) is int


def dispatched_calls(source: str) -> list[tuple[int, str]]:
    """(line, expression) of every CPU-dependent operation in a Python source."""
    found = []
    for node in ast.walk(ast.parse(source)):
        hit = False
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
            hit = True
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            exact = isinstance(node.right, ast.Constant) and node.right.value in EXACT_POWERS
            hit = not exact and not (_is_int_constant(node.left) and _is_int_constant(node.right))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            base, name = ast.unparse(node.func.value), node.func.attr
            if base in ("np", "numpy"):
                hit = name in NUMPY_DISPATCHED | NUMPY_BLAS
            elif base in ("np.linalg", "numpy.linalg"):  # a norm along an axis is element-wise
                hit = not (name == "norm" and any(k.arg == "axis" for k in node.keywords))
            elif base == "math":
                hit = name in MATH_DISPATCHED
        if hit:
            found.append((node.lineno, ast.get_source_segment(source, node)))
    return found


def _sources() -> list[Path]:
    files = [f for d in SCANNED for f in sorted((ROOT / d).rglob("*.py"))]
    return [f for f in files if f.name != "portable_math.py"]  # the reference implementations live there


def test_the_scanner_finds_each_kind_of_dispatched_call():
    """The scanner itself: each kind it must catch, and the exact forms it must let through."""
    caught = ["a @ b", "np.arctan2(y, x)", "np.sin(t)", "t ** 3", "x ** 1.5", "math.atan2(y, x)", "math.exp(x)",
              "np.linalg.norm(v)", "np.linalg.inv(m)", "np.linalg.svd(m)", "np.dot(a, b)", "numpy.exp(x)"]
    for expr in caught:
        assert [e for _, e in dispatched_calls(expr)] == [expr], expr
    for expr in ("x ** 2", "x ** 0.5", "2 ** 63", "np.linalg.norm(v, axis=1)", "np.sqrt(x)", "np.radians(a)",
                 "math.sqrt(x)", "portable_math.atan2(y, x)"):
        assert dispatched_calls(expr) == [], expr


def test_no_cpu_dependent_maths_in_the_generator_trajectories_and_exporters():
    problems, used = [], set()
    for path in _sources():
        rel = path.relative_to(ROOT).as_posix()
        for line, expr in dispatched_calls(path.read_text()):
            if (rel, expr) in ALLOWED:
                used.add((rel, expr))
            else:
                problems.append(f"{rel}:{line}: {expr}")
    assert not problems, (
        "CPU-dependent maths (its rounding changes with the machine, so a seed's bytes would too): use "
        "generator.geometry.portable_math (sin, cos, atan2, hypot, vector_norm), camera.matmul_exact, "
        "rows_times, apply_affine, affine_inverse or nearest_rotation, or add the line to ALLOWED with "
        "the reason it cannot change a byte:\n" + "\n".join(problems))
    assert used == set(ALLOWED), f"ALLOWED lists code that is gone: {sorted(set(ALLOWED) - used)}"
