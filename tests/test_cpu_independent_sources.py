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
NUMPY_DISPATCHED = {"sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh", "arcsinh",
                    "arccosh", "arctanh", "exp", "exp2", "expm1", "log", "log1p", "log2", "log10", "logaddexp",
                    "logaddexp2", "power", "float_power", "cbrt", "hypot", "angle", "sinc"}
NUMPY_BLAS = {"dot", "matmul", "inner", "vdot", "vecdot", "tensordot", "outer", "convolve", "correlate", "cov",
              "corrcoef", "polyfit"}
MATH_DISPATCHED = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh", "acosh",
                   "atanh", "exp", "exp2", "expm1", "log", "log1p", "log2", "log10", "pow", "hypot", "dist", "cbrt"}

# (file, expression): why it cannot change a byte of a seed's output
ALLOWED = {
    ("generator/blender/extract.py", "np.linalg.det(f.world[:3, :3])"): "only its sign (a mirrored object)",
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
    ("generator/blender/shutter.py", "previous.dot(rotation)"):
        "only its sign, of two rotations a frame apart (near +-1): which of q and -q keys the camera's path",
}


def _is_int_constant(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and type(node.value) is int


def _elementwise_norm(call: ast.Call) -> bool:
    """np.linalg.norm along a given axis with the default order: a square root of a sum of
    squares, element-wise (any other order, or no axis, goes to BLAS or the SVD)."""
    keywords = {k.arg: k.value for k in call.keywords}
    axis = keywords.get("axis")
    default_order = len(call.args) == 1 and ("ord" not in keywords or ast.unparse(keywords["ord"]) == "None")
    return default_order and axis is not None and ast.unparse(axis) != "None"


def _flagged(node: ast.AST) -> bool:
    if isinstance(node, (ast.BinOp, ast.AugAssign)) and isinstance(node.op, ast.MatMult):
        return True
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):  # Python's pow is the C library's
        return not (_is_int_constant(node.left) and _is_int_constant(node.right))
    if isinstance(node, ast.AugAssign) and isinstance(node.op, ast.Pow):
        return True
    if isinstance(node, ast.ImportFrom):  # names that the calls below would no longer show
        module, names = node.module or "", {a.name for a in node.names}
        return (module.endswith("linalg") or (module == "math" and bool(names & MATH_DISPATCHED))
                or (module == "numpy" and bool(names & (NUMPY_DISPATCHED | NUMPY_BLAS))))
    if isinstance(node, ast.Import):
        return any(a.name.endswith("linalg") for a in node.names)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
        return node.func.id == "pow"
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
        base, name = ast.unparse(node.func.value), node.func.attr
        if name == "dot":  # x.dot(y) as well as np.dot
            return True
        if base in ("np", "numpy"):
            if name == "einsum":  # optimize= hands contractions to BLAS
                return any(k.arg == "optimize" and ast.unparse(k.value) != "False" for k in node.keywords)
            return name in NUMPY_DISPATCHED | NUMPY_BLAS
        if base.endswith("linalg"):  # numpy's and scipy's
            return not (name == "norm" and _elementwise_norm(node))
        if base == "math":
            return name in MATH_DISPATCHED
    return False


def dispatched_calls(source: str) -> list[tuple[int, str]]:
    """(line, expression) of every CPU-dependent operation in a Python source."""
    return [(node.lineno, ast.get_source_segment(source, node)) for node in ast.walk(ast.parse(source))
            if _flagged(node)]


def _sources() -> list[Path]:
    files = [f for d in SCANNED for f in sorted((ROOT / d).rglob("*.py"))]
    return [f for f in files if f.name != "portable_math.py"]  # the reference implementations live there


def test_the_scanner_finds_each_kind_of_dispatched_call():
    """The scanner itself: each kind it must catch, and the exact forms it must let through."""
    caught = ["a @ b", "np.arctan2(y, x)", "np.sin(t)", "t ** 3", "x ** 1.5", "x ** 2", "math.atan2(y, x)",
              "math.exp(x)", "np.linalg.norm(v)", "np.linalg.norm(v, axis=None)", "np.linalg.norm(v, 2, axis=1)",
              "np.linalg.norm(m, ord='nuc', axis=(0, 1))", "np.linalg.inv(m)", "np.linalg.svd(m)",
              "scipy.linalg.expm(m)", "np.dot(a, b)", "a.T.dot(b)", "numpy.exp(x)", "np.arcsinh(x)",
              "np.angle(z)", "pow(x, 3)", "np.einsum('ij,jk->ik', a, b, optimize=True)",
              "from numpy.linalg import inv", "from math import sin, sqrt", "from numpy import arctan2",
              "import numpy.linalg as la"]
    for expr in caught:
        assert [e for _, e in dispatched_calls(expr)] == [expr], expr
    assert len(dispatched_calls("x @= y")) == 1 and len(dispatched_calls("x **= 3")) == 1
    for expr in ("2 ** 63", "np.linalg.norm(v, axis=1)", "np.linalg.norm(v, axis=-1, keepdims=True)", "np.sqrt(x)",
                 "np.radians(a)", "math.sqrt(x)", "math.fsum(v)", "portable_math.atan2(y, x)",
                 "np.einsum('ij,ij->i', a, b)", "from math import sqrt, pi", "from numpy.random import default_rng"):
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
