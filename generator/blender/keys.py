"""Object keys: the strings ``Simulator.object_names`` holds, one per simulated object (bpy-free).

An object is keyed by its name; a copy made by instancing by ``instancer/object#id`` (``id``
the instance's persistent id, numbers joined by ``-``). Any name is allowed, so the three
characters with a meaning in keys are escaped in each name: ``%`` as ``%25``, ``/`` as ``%2F``
and ``#`` as ``%23`` (percent-encoding of those three only). A name without them is its own
key, and two objects never share a key: an object named ``Inst/Cube#0`` is
``Inst%2FCube%230``, the cube ``Cube`` instanced by ``Inst`` is ``Inst/Cube#0``.
"""

from __future__ import annotations

import re

_ESCAPES = {"%": "%25", "/": "%2F", "#": "%23"}
_SPECIAL = re.compile(r"[%/#]")
_ESCAPED = re.compile(r"%(25|2F|23)")


def escape_name(name: str) -> str:
    """``name`` with ``%``, ``/`` and ``#`` percent-encoded (unchanged without them)."""
    return _SPECIAL.sub(lambda m: _ESCAPES[m.group(0)], name)


def unescape_name(text: str) -> str:
    """The inverse of :func:`escape_name`."""
    return _ESCAPED.sub(lambda m: chr(int(m.group(1), 16)), text)


def object_key(name: str) -> str:
    """Key of an object that is not an instance."""
    return escape_name(name)


def instance_key(instancer: str, name: str, persistent_id: str) -> str:
    """Key of the copy of object ``name`` that ``instancer`` makes (``persistent_id``: its
    numbers joined by ``-``)."""
    return f"{escape_name(instancer)}/{escape_name(name)}#{persistent_id}"


def key_names(key: str) -> tuple[str | None, str]:
    """(instancer name or None, object name) of a key."""
    if "/" not in key:
        return None, unescape_name(key)
    head, tail = key.split("/", 1)
    return unescape_name(head), unescape_name(tail.rsplit("#", 1)[0])


def owner_name(key: str) -> str:
    """The object a key goes by in ``filter_object_names``: an instance's instancer, else the object."""
    instancer, name = key_names(key)
    return name if instancer is None else instancer
