"""Occlusion tests straight into Embree 4, the library the bpy wheel ships (``bpy/lib``).

The segments go to Embree in packets of 8 (its native width on AVX2 machines) from a numba
kernel, on every core (``numba.get_num_threads()``), into a structure built at Embree's high
quality (spatial splits); a packet goes through the static scene, then the dynamic one with
the rays still open. The answer of a segment is Embree's: does any triangle cross it (``tnear``
0, ``tfar`` 1, unnormalised directions, as open3d's ``test_occlusions`` takes them). The
library's back-face culling is off (checked when the device is made), so a triangle blocks
from both sides, as in open3d. On the benchmark's site, 1.3x faster than the same rays
through ``test_occlusions`` (docs/benchmarks.md, visibility).

Visibility (rule 4 of docs/conventions.md) and every other occlusion test of
``SceneGeometry.rays_blocked`` go through here; first hits, distances and inside tests stay on
open3d (``structure.py``), whose structures are then built at their own first query.
The library is loaded at the first use, not at import.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import importlib.util
import os
import types as types_
import weakref
from collections.abc import Sequence

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from .parts import MeshPart

# Embree 4's enums (rtcore_*.h)
_TRIANGLE, _INDEX, _VERTEX = 0, 0, 1
_UINT3, _FLOAT3 = 0x5003, 0x9003
BUILD_HIGH, BUILD_MEDIUM = 2, 1
_PROPERTY_BACKFACE_CULLING = 65
PACKET = 8
# one RTCRay8 (12 lanes of 8 x 4 bytes: origin, tnear, direction, time, tfar, mask, id,
# flags) then its valid mask (8 int32), per thread; 32-byte aligned
RAY8_FLOATS, SLOT_FLOATS = 96, 128


def _library_path() -> str:
    spec = importlib.util.find_spec("bpy")
    found = sorted(glob.glob(os.path.join(os.path.dirname(spec.origin), "lib", "*embree4*"))) if spec else []
    if not found:
        raise RuntimeError("Embree 4 not found in the bpy wheel (bpy/lib/libembree4.*): reinstall with "
                           "`bash tools/bootstrap.sh` (pinned bpy)")
    return found[0]


_U64 = ctypes.c_uint64  # handles and pointers, passed as integers (the same ABI on x86-64 and arm64)
# name: (result, arguments) of the Embree functions used here
_SIGNATURES = {
    "rtcNewDevice": (_U64, [ctypes.c_char_p]),
    "rtcGetDeviceProperty": (ctypes.c_ssize_t, [_U64, ctypes.c_int]),
    "rtcGetDeviceError": (ctypes.c_int, [_U64]),
    "rtcNewScene": (_U64, [_U64]),
    "rtcNewGeometry": (_U64, [_U64, ctypes.c_int]),
    "rtcSetNewGeometryBuffer": (_U64, [_U64, ctypes.c_int, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t,
                                       ctypes.c_size_t]),
    "rtcCommitGeometry": (None, [_U64]),
    "rtcAttachGeometry": (ctypes.c_uint, [_U64, _U64]),
    "rtcReleaseGeometry": (None, [_U64]),
    "rtcSetSceneBuildQuality": (None, [_U64, ctypes.c_int]),
    "rtcCommitScene": (None, [_U64]),
    "rtcReleaseScene": (None, [_U64]),
}


@functools.cache
def _api() -> types_.SimpleNamespace:
    """The library's functions (loaded at the first use, not at import: the other packages
    import this module's users without ever casting a ray)."""
    lib = ctypes.CDLL(_library_path())
    api = types_.SimpleNamespace()
    for name, (result, arguments) in _SIGNATURES.items():
        function = getattr(lib, name)
        function.restype, function.argtypes = result, arguments
        setattr(api, name[3:], function)  # rtcNewScene -> api.NewScene
    # rtcOccluded8(const int* valid, RTCScene, RTCRay8*, RTCOccludedArguments* (NULL: defaults)),
    # called from the kernels below by its address (a cached kernel holds no ctypes object)
    api.occluded8 = np.uint64(ctypes.cast(lib.rtcOccluded8, ctypes.c_void_p).value)
    return api


_device = {"pid": None, "handle": 0}


def device() -> int:
    """This process's Embree device (made at the first call, and again in a forked child)."""
    if _device["pid"] != os.getpid():
        api = _api()
        handle = api.NewDevice(None)
        if not handle:
            raise RuntimeError(f"Embree could not start (error {api.GetDeviceError(0)})")
        if api.GetDeviceProperty(handle, _PROPERTY_BACKFACE_CULLING) != 0:
            raise RuntimeError("this Embree culls back faces; occlusion tests need both sides")
        _device.update(pid=os.getpid(), handle=handle)
    return _device["handle"]


class OcclusionScene:
    """One Embree scene over some parts (their triangles at the current matrices)."""

    def __init__(self, parts: Sequence[MeshPart], quality: int = BUILD_HIGH):
        dev, api = device(), _api()
        self.handle = api.NewScene(dev)
        self.count = 0
        for part in parts:
            if len(part.faces) == 0:
                continue
            vertices = np.ascontiguousarray(part.world_vertices(), dtype=np.float32)
            faces = np.ascontiguousarray(part.faces, dtype=np.uint32)
            geometry = api.NewGeometry(dev, _TRIANGLE)
            for kind, form, array in ((_VERTEX, _FLOAT3, vertices), (_INDEX, _UINT3, faces)):
                ctypes.memmove(api.SetNewGeometryBuffer(geometry, kind, 0, form, 12, len(array)), array.ctypes.data,
                               array.nbytes)
            api.CommitGeometry(geometry)
            api.AttachGeometry(self.handle, geometry)
            api.ReleaseGeometry(geometry)
            self.count += 1
        api.SetSceneBuildQuality(self.handle, quality)
        api.CommitScene(self.handle)
        error = api.GetDeviceError(dev)
        if error:
            raise RuntimeError(f"Embree could not build the scene (error {error})")
        self._release = weakref.finalize(self, api.ReleaseScene, self.handle)


def occluded(scenes: Sequence[OcclusionScene], rays: np.ndarray) -> np.ndarray:
    """For float32 rays (N, 6) [origin, direction]: does any triangle of any of ``scenes``
    cross the segment from the origin to origin + direction? (N,) bool."""
    out = np.zeros(len(rays), dtype=np.bool_)
    handles = scene_handles(scenes)
    if len(rays) == 0 or len(handles) == 0:
        return out
    chunks = max(1, min(numba.get_num_threads(), -(-len(rays) // (4 * PACKET))))
    slots = packet_slots(chunks)
    _occluded_chunks(handles, _api().occluded8, np.ascontiguousarray(rays, dtype=np.float32), out, slots,
                     np.uint64(slots.ctypes.data), chunks)
    return out


def scene_handles(scenes: Sequence[OcclusionScene]) -> np.ndarray:
    """The handles (uint64) of the scenes that hold triangles, in order."""
    return np.array([s.handle for s in scenes if s.count], dtype=np.uint64)


def packet_slots(count: int) -> np.ndarray:
    """Memory for ``count`` threads' RTCRay8 and valid mask (:func:`cast_packets`), 64-byte aligned."""
    floats = count * SLOT_FLOATS
    raw = np.zeros(floats + 16, dtype=np.float32)
    skip = (-raw.ctypes.data % 64) // 4
    return raw[skip:skip + floats]


@intrinsic
def _call4(typingctx, function, a, b, c):
    """Call the C function at address ``function`` with (a, b, c, NULL), all 64-bit."""
    sig = types.void(types.uint64, types.uint64, types.uint64, types.uint64)

    def codegen(context, builder, signature, args):
        word = ir.IntType(64)
        pointer = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [word] * 4).as_pointer())
        builder.call(pointer, [args[1], args[2], args[3], ir.Constant(word, 0)])
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True, nogil=True)
def cast_packets(scenes, function, rays, lo, hi, out, slot, slot_address):
    """Rays lo..hi (rows of ``rays``) into Embree (``function``: rtcOccluded8's address),
    PACKET at a time, through one thread's ``slot`` (SLOT_FLOATS float32 at
    ``slot_address``); a packet goes through ``scenes`` in turn with the rays no scene before
    has blocked. ``out[row]`` is set for every blocked ray."""
    lanes = slot.view(np.int32)
    valid = RAY8_FLOATS  # the valid mask follows the packet
    valid_address = slot_address + np.uint64(4 * valid)
    for first in range(lo, hi, PACKET):
        m = min(PACKET, hi - first)
        for k in range(PACKET):
            if k < m:
                r = first + k
                for a in range(3):
                    slot[8 * a + k] = rays[r, a]  # origin
                    slot[32 + 8 * a + k] = rays[r, 3 + a]  # direction
                slot[24 + k] = 0.0  # tnear
                slot[56 + k] = 0.0  # time
                slot[64 + k] = 1.0  # tfar
                lanes[72 + k] = -1  # mask: every geometry
                lanes[80 + k] = 0  # id
                lanes[88 + k] = 0  # flags
                lanes[valid + k] = -1
            else:
                lanes[valid + k] = 0
        for scene in scenes:
            _call4(function, valid_address, scene, slot_address)
            left = 0
            for k in range(m):
                if slot[64 + k] < 0.0:  # Embree sets tfar to -inf on a hit
                    lanes[valid + k] = 0
                else:
                    left += 1
            if left == 0:
                break
        for k in range(m):
            out[first + k] = slot[64 + k] < 0.0


@numba.njit(cache=True, nogil=True, parallel=True)
def _occluded_chunks(scenes, function, rays, out, slots, slots_address, chunks):
    n = len(rays)
    packets = (n + PACKET - 1) // PACKET
    for c in numba.prange(chunks):  # contiguous runs (interleaved ones share out's cache lines: slower)
        lo = min(n, PACKET * (packets * c // chunks))
        hi = min(n, PACKET * (packets * (c + 1) // chunks))
        cast_packets(scenes, function, rays, lo, hi, out, slots[c * SLOT_FLOATS:(c + 1) * SLOT_FLOATS],
                     slots_address + np.uint64(4 * c * SLOT_FLOATS))
