#!/usr/bin/env python3
"""Seed corpora for the fuzz/ harnesses (scripts/fuzz.sh): the repo's own scenes and test corpus whole, the
small shared SPD scenes whole and cut-down versions of the large shared meshes and scenes (the first
vertices and the faces among them, headers rewritten), so that seeds stay a few KB and mutations are fast.
Usage: make_seeds.py SOURCE_DIR SHARED_DATA_DIR OUT_DIR (one folder per harness under OUT_DIR)."""
import struct
import sys
from pathlib import Path

SMALL = 8192  # bytes: a shared scene up to this size is taken whole
KEEP_VERTICES = 64


def write(folder: Path, name: str, data: bytes) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)


def copy_glob(folder: Path, sources: Path, pattern: str) -> None:
    for source in sorted(sources.glob(pattern)):
        if source.stat().st_size <= SMALL:
            write(folder, source.name, source.read_bytes())


def off_prefix(text: str) -> bytes:
    """The first KEEP_VERTICES vertices of an OFF file and the faces that use only them."""
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    vertex_count, face_count = (int(v) for v in lines[1].split()[:2])
    vertices = lines[2:2 + min(vertex_count, KEEP_VERTICES)]
    faces = [f for f in lines[2 + vertex_count:2 + vertex_count + face_count]
             if all(int(i) < len(vertices) for i in f.split()[1:])]
    return ("OFF\n%d %d 0\n" % (len(vertices), len(faces)) + "\n".join(vertices + faces) + "\n").encode()


def ply_prefix(data: bytes) -> bytes:
    """The first KEEP_VERTICES vertices (x y z floats) of a PLY file and the faces among them, same encoding."""
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode()
    vertex_count = int(header.split("element vertex ")[1].split()[0])
    face_count = int(header.split("element face ")[1].split()[0])
    kept = min(vertex_count, KEEP_VERTICES)
    if "format ascii" in header:
        lines = data[end:].decode().splitlines()
        vertices = lines[:kept]
        faces = [f for f in lines[vertex_count:vertex_count + face_count]
                 if all(int(i) < kept for i in f.split()[1:])]
        body = ("\n".join(vertices + faces) + "\n").encode()
    else:  # binary_little_endian, float x y z, list uchar int
        vertices = data[end:end + 12 * kept]
        position, faces = end + 12 * vertex_count, []
        for _ in range(face_count):
            n = data[position]
            indices = struct.unpack_from("<%di" % n, data, position + 1)
            if all(i < kept for i in indices):
                faces.append(data[position:position + 1 + 4 * n])
            position += 1 + 4 * n
            if len(faces) >= 4 * KEEP_VERTICES:
                break
        body = vertices + b"".join(faces)
    header = header.replace("element vertex %d" % vertex_count, "element vertex %d" % kept)
    header = header.replace("element face %d" % face_count, "element face %d" % len(faces))
    return header.encode() + body


def obj_prefix(text: str, face_count: int = 48) -> bytes:
    """The first `face_count` `f` lines of an OBJ file with the `v` lines they use, renumbered in order."""
    vertices = [line for line in text.splitlines() if line.startswith("v ")]
    faces = [line.split()[1:] for line in text.splitlines() if line.startswith("f ")][:face_count]
    used = {}
    for face in faces:
        for index in face:
            used.setdefault(int(index.split("/")[0]), len(used) + 1)
    lines = [vertices[old - 1] for old in used]
    lines += ["f " + " ".join(str(used[int(i.split("/")[0])]) for i in face) for face in faces]
    return ("\n".join(lines) + "\n").encode()


def nff_prefix(text: str, size: int = 4096) -> bytes:
    """About `size` bytes of an NFF file, cut before an entity keyword so that the prefix still parses."""
    lines, kept, total = text.splitlines(), [], 0
    for line in lines:
        if total > size and line.split()[:1] and line.split()[0] in ("p", "pp", "s", "c", "f"):
            break
        kept.append(line)
        total += len(line) + 1
    return ("\n".join(kept) + "\n").encode()


def rays_seed(triangles, rays) -> bytes:
    """The rays harness's input for the given triangles and rays, every value a multiple of 1/16 in
    [-5, 5) (one tag byte each). FuzzedDataProvider takes integers from the end of the input, so the bytes
    are written in consumption order and reversed."""
    def tag(value: float) -> int:
        code = round(value * 16) + 80
        assert 0 <= code < 160 and (code - 80) / 16 == value, value
        return code
    consumed = [len(triangles)]
    for triangle in triangles:
        consumed += [tag(c) for vertex in triangle for c in vertex]
    consumed.append(0)  # no sphere
    for origin, direction, tnear, tfar in rays:
        consumed += [tag(c) for c in origin + direction] + [tag(tnear)]
        consumed += [1] if tfar is None else [0, tag(tfar)]
    return bytes(reversed(consumed))


def instances_seed() -> bytes:
    """instances_fuzz's input: a unit quad (two triangles sharing an edge) placed three times (turned about
    z, side by side, the third a copy of the second: a tie), the first moved up after the first trace, a
    camera tile aimed at the first quad's centre, shadow rays towards a light above, and three raw rays
    along the quads' edges and through a vertex. Every value a multiple of 1/16 in [-5, 5) (one tag byte),
    the bytes in consumption order, reversed (FuzzedDataProvider takes integers from the end)."""
    def tags(*values) -> list:
        return [round(v * 16) + 80 for v in values]
    placed = lambda axis, angle, scale, offset: [0] + tags(*axis, angle, *scale, *offset)  # structured
    consumed = [0, 1]                                                    # one object of two triangles
    consumed += tags(0, 0, 0, 1, 0, 0, 1, 1, 0)
    consumed += [0] + tags(0, 0, 0, 1, 1, 0, 0, 1, 0)                    # its own first vertex
    consumed += [2]                                                      # three instances
    consumed += placed((0, 0, 1), 0.5, (1, 1, 1), (-2, 0, 0))
    consumed += [1] + placed((0, 0, 1), 0, (1, 1, 1), (1, 0, 0))
    consumed += [0]                                                      # a copy of the second
    consumed += [1] + placed((0, 0, 1), 0.5, (1, 1, 1), (-2, 1, 0))      # the first moved
    consumed += tags(-1.5, 0.5, 4, -1.5, 0.5, 0, 0.0625) + [1, 1]        # the camera tile
    consumed += tags(0, 4, 3, -3, 0.25, -0.5, 0.25, 0, 0.125)           # the shadow tile
    for origin, direction in (((0.5, 0.5, 1), (0, 0, -1)), ((1, 1, 1), (0, 0, -1)), ((-3, 0, 0), (1, 0, 0))):
        consumed += tags(*origin, *direction, 0) + [1]
    return bytes(reversed(consumed))


MESH_RAYS_SCENES = 5  # the fixed scenes of mesh_rays_fuzz.cpp, in its order


def mesh_rays_seed(scene: int, triangle: int) -> bytes:
    """mesh_rays_fuzz's input: the scene index, then five rays about one triangle: from the exact centre to
    a vertex (as it is, scaled by a power of two, nudged by a few floats), from a vertex to an edge midpoint
    (tfar = 1, at the edge), and from a lattice point near the scene into the triangle. Bytes in consumption
    order (FuzzedDataProvider takes integers from the end; a uint16 high byte first), reversed."""
    consumed = [scene]

    def triangle_point(kind: int, triangle: int, corner: int, parameters=()) -> list:
        return [kind, triangle >> 8, triangle & 255, corner] + list(parameters)

    vertex = triangle_point(0, triangle, triangle % 3)
    consumed += [3, 1] + vertex + [1, 0]                        # centre -> vertex, [0, inf]
    consumed += [3, 2] + vertex + [0, triangle % 256] + [1, 0]  # the same scaled by 2^(triangle % 256 - 160)
    consumed += [3, 3] + vertex + [triangle % 3, triangle % 9, 1, 0]  # one component a few floats off
    consumed += [0, triangle >> 8, triangle & 255, 1, 1] + triangle_point(1, triangle + 1, 2, [8]) + [1, 1]
    consumed += [4, 88, 72, 96, 1] + triangle_point(2, triangle, 0, [5, 5]) + [1, 0]
    return bytes(reversed(consumed))


def main() -> None:
    source, shared, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
    test_data = source / "tests/scene/data"
    for harness, extension in (("off_fuzz", "off"), ("nff_fuzz", "nff"), ("ply_fuzz", "ply"), ("obj_fuzz", "obj")):
        for kind in ("good", "broken"):
            copy_glob(out / harness, test_data / kind, "*." + extension)
    write(out / "nff_fuzz", "default_prefix.nff", nff_prefix((source / "scenes/default.nff").read_text()))
    for dsc in sorted(test_data.glob("*/*.dsc")):
        off = dsc.with_suffix(".off")
        write(out / "dsc_fuzz", dsc.parent.name + "_" + dsc.stem,
              dsc.read_bytes() + (b"\0" + off.read_bytes() if off.exists() else b""))
    if shared.is_dir():
        for nff in sorted((shared / "spd").glob("*.nff")):
            text = nff.read_text()
            write(out / "nff_fuzz", nff.name, text.encode() if len(text) <= SMALL else nff_prefix(text))
        for mesh in sorted((shared / "meshes").iterdir()):
            if mesh.suffix == ".off":
                write(out / "off_fuzz", mesh.name, off_prefix(mesh.read_text()))
                dsc = b"DSC\n64 64\n2 1\n1 0 0 0.2 0.8 1\n0 1 0 0 0.5 1.5\n10 10 10 1 1 1\n"
                prefix = off_prefix(mesh.read_text())
                faces = int(prefix.split(b"\n")[1].split()[1])
                dsc += b"%d\n" % faces + b"".join(b"%d\n" % (i % 2) for i in range(faces))
                write(out / "dsc_fuzz", mesh.stem, dsc + b"\0" + prefix)
            elif mesh.suffix == ".ply":
                write(out / "ply_fuzz", mesh.name, ply_prefix(mesh.read_bytes()))
            elif mesh.suffix == ".obj":
                write(out / "obj_fuzz", mesh.name, obj_prefix(mesh.read_text()))
        # The first polygons of tetra.nff: its coordinates are multiples of 1/16 inside [-5, 5).
        triangles = []
        for line in (shared / "spd/tetra.nff").read_text().splitlines():
            values = line.split()
            if len(values) == 3 and all(v.lstrip("-").replace(".", "").isdigit() for v in values):
                triangles.append([float(v) for v in values])
        triangles = [triangles[i:i + 3] for i in range(0, 24, 3)]
        write(out / "rays_fuzz", "tetra", rays_seed(triangles, [([-4, -4, -4], [1, 1, 1], 0, None),
                                                                  ([0, 0, -4], [-1, -1, 1], 0, 4.5)]))
    quad = [[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]]
    aimed = [([0.5, 0.5, 1], [0, 0, -1], 0, None),    # the shared edge
             ([1, 1, 1], [0, 0, -1], 0, None),        # a shared vertex
             ([0.25, 0.75, -1], [0, 0, 1], 0, 1),     # from behind, tfar exactly at the hit
             ([-1, 0.5, 0], [1, 0, 0], 0, None),      # in the plane of the quad
             ([0.5, 0.5, 1], [0, 0, -1], 2, 1)]       # tnear > tfar
    write(out / "rays_fuzz", "quad", rays_seed(quad, aimed))
    write(out / "instances_fuzz", "quads", instances_seed())
    for scene in range(MESH_RAYS_SCENES):
        for triangle in range(0, 1280, 97):
            write(out / "mesh_rays_fuzz", "scene%d_%d" % (scene, triangle), mesh_rays_seed(scene, triangle))


if __name__ == "__main__":
    main()
