"""glTF files checked before trimesh reads them: a 600-byte .gltf may name a 1.2 GB .bin
beside it (the mesh-file limit was bypassed, and trimesh read it all before failing), and
views or accessors past the end of their buffer ended in numpy's "cannot reshape". Each
problem is one reason naming the glTF field (`buffers.0.uri: ...`)."""

from __future__ import annotations

import json
import os
import struct
from urllib.parse import unquote

from ..config.files import file_problem

COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9,
                   "MAT4": 16}


class GltfProblem(ValueError):
    """What is wrong with a glTF file, as `field: reason`."""


def gltf_problem(path: str, limit: int) -> str | None:
    """Why the glTF (.gltf or .glb) at `path` cannot be read within `limit` bytes in all,
    its external buffers and images included; None for other files or a sound one."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".gltf", ".glb"):
        return None
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
        doc, embedded = _glb(data) if ext == ".glb" else (_json(data), None)
        if not isinstance(doc, dict):
            raise GltfProblem("not a glTF file (no JSON object)")
        sizes = _buffers(doc, os.path.dirname(path), limit - len(data), embedded)
        _views_and_accessors(doc, sizes)
    except GltfProblem as e:
        return str(e)
    except OSError as e:
        return f"cannot read ({e.strerror})"
    return None


def _json(data: bytes):
    try:
        return json.loads(data)
    except (ValueError, RecursionError) as e:
        raise GltfProblem(f"not a glTF file ({str(e).splitlines()[0]})") from None


def _glb(data: bytes) -> tuple:
    """(JSON document, length of the BIN chunk or None) of a binary glTF."""
    if len(data) < 20 or data[:4] != b"glTF":
        raise GltfProblem("not a binary glTF file (no glTF header)")
    length, kind = struct.unpack_from("<I4s", data, 12)
    if kind != b"JSON" or 20 + length > len(data):
        raise GltfProblem("not a binary glTF file (no whole JSON chunk)")
    doc = _json(data[20:20 + length])
    rest = 20 + length + (-length % 4)
    if rest + 8 <= len(data):
        size, kind = struct.unpack_from("<I4s", data, rest)
        if kind == b"BIN\0":
            return doc, min(size, len(data) - rest - 8)
    return doc, None


def _items(doc: dict, key: str) -> list:
    items = doc.get(key, [])
    if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
        raise GltfProblem(f"{key}: must be a list of objects")
    return items


def _count(item: dict, key: str, field: str, default: int | None = None) -> int:
    value = item.get(key, default)
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise GltfProblem(f"{field}: must be an integer >= 0")
    return value


def _external(uri, folder: str, budget: int, field: str) -> int:
    """The size of the file a relative URI names, refused unless it is a regular file
    inside `folder` within `budget` bytes."""
    if not isinstance(uri, str):
        raise GltfProblem(f"{field}: must be a string")
    if uri.startswith("data:"):
        return -1  # embedded: counted in the glTF file's own size
    name = unquote(uri)
    if ":" in name.split("/")[0] or name.startswith(("/", "\\")) or os.path.isabs(name):
        raise GltfProblem(f"{field}: must be a path relative to the glTF file: {uri}")
    if ".." in name.replace("\\", "/").split("/"):
        raise GltfProblem(f"{field}: must stay in the glTF file's folder: {uri}")
    reason = file_problem(os.path.join(folder, name), max(budget, 0), "mesh file and its buffers")
    if reason is not None:
        raise GltfProblem(f"{field}: {reason}: {uri}")
    return os.path.getsize(os.path.join(folder, name))


def _buffers(doc: dict, folder: str, budget: int, embedded: int | None) -> list[int]:
    """Each buffer's byteLength, checked against the file holding it."""
    sizes = []
    for i, buffer in enumerate(_items(doc, "buffers")):
        length = _count(buffer, "byteLength", f"buffers.{i}.byteLength")
        if "uri" in buffer:
            have = _external(buffer["uri"], folder, budget, f"buffers.{i}.uri")
            budget -= max(have, 0)
        else:
            have = embedded if i == 0 and embedded is not None else None
            if have is None:
                raise GltfProblem(f"buffers.{i}.uri: required (no binary chunk holds it)")
        if have >= 0 and length > have:
            raise GltfProblem(f"buffers.{i}.byteLength: {length} bytes, but its file holds "
                              f"{have}")
        sizes.append(length)
    for i, image in enumerate(_items(doc, "images")):
        if "uri" in image:
            budget -= max(_external(image["uri"], folder, budget, f"images.{i}.uri"), 0)
    return sizes


def _views_and_accessors(doc: dict, sizes: list[int]) -> None:
    views = []
    for i, view in enumerate(_items(doc, "bufferViews")):
        buffer = _count(view, "buffer", f"bufferViews.{i}.buffer")
        if buffer >= len(sizes):
            raise GltfProblem(f"bufferViews.{i}.buffer: no buffer {buffer}")
        end = (_count(view, "byteOffset", f"bufferViews.{i}.byteOffset", 0)
               + _count(view, "byteLength", f"bufferViews.{i}.byteLength"))
        if end > sizes[buffer]:
            raise GltfProblem(f"bufferViews.{i}: ends at byte {end}, past its buffer's "
                              f"{sizes[buffer]}")
        views.append((view["byteLength"], view.get("byteStride")))
    for i, accessor in enumerate(_items(doc, "accessors")):
        if "bufferView" not in accessor:
            continue  # all zeros (or sparse): nothing read
        index = _count(accessor, "bufferView", f"accessors.{i}.bufferView")
        if index >= len(views):
            raise GltfProblem(f"accessors.{i}.bufferView: no buffer view {index}")
        component = COMPONENT_BYTES.get(accessor.get("componentType"))
        components = TYPE_COMPONENTS.get(accessor.get("type"))
        if component is None or components is None:
            raise GltfProblem(f"accessors.{i}: unknown componentType or type")
        count = _count(accessor, "count", f"accessors.{i}.count")
        element = component * components
        length, stride = views[index]
        stride = stride if isinstance(stride, int) and stride > element else element
        end = (_count(accessor, "byteOffset", f"accessors.{i}.byteOffset", 0)
               + (count - 1) * stride + element) if count else 0
        if end > length:
            raise GltfProblem(f"accessors.{i}.count: {count} elements need {end} bytes; its "
                              f"buffer view has {length}")
