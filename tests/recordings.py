"""Running the viewer's CLI and reading its Rerun recordings back with Rerun's own RRD reader
(rerun.chunk.RrdReader), for tests/test_view*.py."""

import os
import subprocess
import sys
from collections import defaultdict

import pyarrow as pa
from rerun.chunk import RrdReader

from conftest import ROOT


def run_module(*args, env=None, cwd=ROOT, **kw) -> subprocess.CompletedProcess:
    """``python -m *args`` in a real process, output captured."""
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, cwd=cwd, env=env, **kw)


def read_rrd(path) -> dict:
    """entity path -> {"static": pyarrow Table or None, "temporal": pyarrow Table or None}."""
    batches = defaultdict(lambda: defaultdict(list))
    for chunk in RrdReader(path).stream():
        batches[chunk.entity_path]["static" if chunk.is_static else "temporal"].append(chunk.to_record_batch())
    def table(parts):  # chunks of one entity may hold different components: missing ones are null
        return pa.concat_tables([pa.Table.from_batches([b]) for b in parts], promote_options="default")

    return {e: {k: (table(v) if v else None) for k, v in
                (("static", parts.get("static", [])), ("temporal", parts.get("temporal", [])))}
            for e, parts in batches.items()}


def column(table: pa.Table, name: str, sort_by: str | None = None) -> list:
    """A component column as Python values, rows sorted by a timeline (one logged value per row)."""
    if sort_by is not None:
        table = table.sort_by(sort_by)
    return [None if v is None else v[0] if len(v) == 1 else v for v in table.column(name).to_pylist()]


STRICT = os.environ | {"RERUN_STRICT": "1"}  # anything Rerun cannot log raises instead of warning


def view(*args, **kw) -> subprocess.CompletedProcess:
    """``python -m datasets.view *args`` with Rerun in strict mode."""
    return run_module("datasets.view", *map(str, args), env=kw.pop("env", STRICT), **kw)


def blueprint_views(path) -> list[dict]:
    """The default layout's views: class ('2D', '3D', ...), name, origin, contents query."""
    reader = RrdReader(path)
    views = defaultdict(dict)
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        for key, col in (("class", "ViewBlueprint:class_identifier"), ("name", "ViewBlueprint:display_name"),
                         ("origin", "ViewBlueprint:space_origin"), ("query", "ViewContents:query")):
            if col in batch.schema.names:
                value = batch.column(col).to_pylist()[-1]
                views[chunk.entity_path.removesuffix("/ViewContents")][key] = value if key == "query" else value[0]
    return [v for v in views.values() if "class" in v]
