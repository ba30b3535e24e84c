#!/usr/bin/env python3
"""Writes the malformed-input corpus: model files, scenes and meshes of every class issue 13
found (crafted counts and ranges, resource exhaustion, values that escape the parser, messages
without a reason), each with the words its error must contain, into manifest.json.

    tests/malformed/generate.py     # rewrites model/, scene/, mesh/ and manifest.json

The tests (tests/test_malformed_models.cpp, tests/builder/test_malformed_inputs.cpp) read the
manifest: every file must give an fsm::Error whose message contains its words (or, for a
"warning:" entry, build with a warning containing them) - never a crash, a hang, another
exception or an allocation the file did not pay for. Deterministic: the same bytes every run.
The model files are patched from the two valid seeds of the fuzzer (their CRCs recomputed, so
the checks behind the CRC are what is tested)."""
import json
import math
import struct
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
MANIFEST = {}


def expect(path, words):
    MANIFEST[str(path.relative_to(HERE))] = words


# ---- Model files -------------------------------------------------------------------------------

HEADER = 32


def sections(b):
    out, at = [], HEADER
    while at < len(b):
        tag = b[at:at + 4].decode("latin1")
        length = struct.unpack_from("<Q", b, at + 4)[0]
        out.append((tag, at, at + 12, length))
        at += 12 + length
    return out


def section(b, tag):
    for s in sections(b):
        if s[0] == tag:
            return s
    raise KeyError(tag)


def refresh(b):
    b = bytearray(b)
    struct.pack_into("<Q", b, 16, len(b) - HEADER)
    struct.pack_into("<I", b, 24, zlib.crc32(bytes(b[HEADER:])) & 0xFFFFFFFF)
    struct.pack_into("<I", b, 28, zlib.crc32(bytes(b[:28])) & 0xFFFFFFFF)
    return bytes(b)


def set_section_length(b, tag, length):
    b = bytearray(b)
    struct.pack_into("<Q", b, section(b, tag)[1] + 4, length)
    return bytes(b)


def part_fields(b):
    """Offsets of every part's i32 fields in PART (version 2): name -> {field: offset}."""
    _, _, body, _ = section(b, "PART")
    count = struct.unpack_from("<I", b, body)[0]
    at, parts = body + 4, []
    for _ in range(count):
        n = struct.unpack_from("<I", b, at)[0]
        name = b[at + 4:at + 4 + n].decode()
        at += 4 + n
        f = {"topology": at, "region": at + 1, "radius": at + 5}
        at += 13
        for field in ("first_node", "num_nodes", "first_link", "num_links", "surface",
                      "first_tetrahedron", "num_tetrahedra"):
            f[field] = at
            at += 4
        parts.append((name, f))
    return parts


def array_at(b, tag, index):
    """(offset of rows, rows, cols, offset of the first element) of the index-th array of a
    section whose body is only arrays (NODE, LINK) or that starts with arrays."""
    _, _, at, _ = section(b, tag)
    sizes = {"NODE": [8, 8, 8, 8, 8, 4, 1], "LINK": [4, 8, 8, 8, 8, 8]}[tag]
    for k in range(index + 1):
        rows, cols = struct.unpack_from("<II", b, at)
        if k == index:
            return at, rows, cols, at + 8
        at += 8 + rows * cols * sizes[k]


def write_model(name, data, words):
    path = HERE / "model" / name
    path.write_bytes(data)
    expect(path, words)


def patch_i32(b, offset, value):
    b = bytearray(b)
    struct.pack_into("<i", b, offset, value)
    return refresh(b)


def patch(b, offset, fmt, value):
    b = bytearray(b)
    struct.pack_into(fmt, b, offset, value)
    return refresh(b)


def models():
    base = (ROOT / "tests" / "fuzz" / "corpus" / "fuzz_model_file" / "block_v2.fsm").read_bytes()
    parts = dict(part_fields(base))
    block = parts["block"]
    big = 2**31 - 2
    # Crafted counts and ranges behind a valid CRC.
    write_model("part_first_node_near_2_31.fsm", patch_i32(base, block["first_node"], big),
                "node range outside the model")
    write_model("part_num_nodes_huge.fsm", patch_i32(base, block["num_nodes"], big),
                "node range outside the model")
    write_model("part_first_node_negative.fsm", patch_i32(base, block["first_node"], -5),
                "node range outside the model")
    write_model("part_links_past_end.fsm", patch_i32(base, block["num_links"], 100000),
                "link range outside the model")
    write_model("part_first_link_near_2_31.fsm", patch_i32(base, block["first_link"], big),
                "link range outside the model")
    write_model("part_region_out_of_range.fsm", patch_i32(base, block["region"], 7), "bad region")
    write_model("part_surface_out_of_range.fsm", patch_i32(base, block["surface"], 3),
                "surface index out of range")
    write_model("part_surface_below_minus_one.fsm", patch_i32(base, block["surface"], -9),
                "surface index out of range")
    write_model("part_tetrahedra_near_2_31.fsm", patch_i32(base, block["first_tetrahedron"], big),
                "tetrahedron range outside the model")
    write_model("part_tetrahedra_count_huge.fsm", patch_i32(base, block["num_tetrahedra"], big),
                "tetrahedron range outside the model")
    write_model("part_topology_unknown.fsm", patch(base, block["topology"], "<B", 9),
                "unknown topology 9")
    write_model("part_radius_nan.fsm", patch(base, block["radius"], "<d", math.nan),
                "radius")
    _, _, atch, _ = section(base, "ATCH")
    write_model("attachment_first_near_2_31.fsm", patch_i32(base, atch, big),
                "attachments: link range outside the model")
    write_model("attachment_count_past_links.fsm", patch_i32(base, atch + 4, 5000),
                "attachments: link range outside the model")
    write_model("attachment_count_negative.fsm", patch_i32(base, atch + 4, -1),
                "attachments: link range outside the model")
    _, _, skin, _ = section(base, "SKIN")
    vrows = struct.unpack_from("<I", base, skin)[0]
    faces_at = skin + 8 + vrows * 24
    frows = struct.unpack_from("<I", base, faces_at)[0]
    surfaces_at = faces_at + 8 + frows * 12
    name_len = struct.unpack_from("<I", base, surfaces_at + 4)[0]
    surface = surfaces_at + 8 + name_len  # first_vertex, num_vertices, first_face, num_faces
    write_model("skin_surface_first_vertex_near_2_31.fsm", patch_i32(base, surface, big),
                "range outside the skin")
    write_model("skin_surface_vertex_count_huge.fsm", patch_i32(base, surface + 4, big),
                "range outside the skin")
    write_model("skin_surface_faces_past_end.fsm", patch_i32(base, surface + 12, frows + 1),
                "range outside the skin")
    write_model("skin_face_vertex_out_of_range.fsm", patch_i32(base, faces_at + 8, 100000),
                "skin")
    kinds_at = surfaces_at + 8 + name_len + 16
    write_model("skin_kind_unknown.fsm", patch(base, kinds_at + 8, "<B", 7),
                "unknown binding kind 7")
    nodes_at = kinds_at + 8 + vrows
    write_model("skin_node_out_of_range.fsm", patch_i32(base, nodes_at + 8, 99999),
                "sphere index out of range")
    weights_at = nodes_at + 8 + vrows * 16
    write_model("skin_weight_nan.fsm", patch(base, weights_at + 8, "<d", math.nan), "not finite")
    write_model("skin_weights_not_summing.fsm", patch(base, weights_at + 8, "<d", 5.0),
                "barycentric weights do not sum to 1")
    # Tetrahedra.
    _, _, tets, _ = section(base, "TETS")
    write_model("tetrahedron_node_out_of_range.fsm", patch_i32(base, tets + 8, 100000),
                "node index out of range")
    write_model("tetrahedron_node_negative.fsm", patch_i32(base, tets + 8, -1),
                "node index out of range")
    t = struct.unpack_from("<4i", base, tets + 8)
    swapped = bytearray(base)
    struct.pack_into("<4i", swapped, tets + 8, t[0], t[1], t[3], t[2])
    write_model("tetrahedron_inverted.fsm", refresh(swapped), "inverted or degenerate at rest")
    degenerate = bytearray(base)
    struct.pack_into("<4i", degenerate, tets + 8, t[0], t[1], t[1], t[2])
    write_model("tetrahedron_repeated_node.fsm", refresh(degenerate), "repeats a node")
    write_model("tetrahedra_rows_near_2_31.fsm", patch(base, tets, "<I", 2**31 - 1), "truncated")
    write_model("tetrahedra_rows_over_index.fsm", patch(base, tets, "<I", 2**32 - 1),
                "more than an Index can count")
    write_model("tetrahedra_three_columns.fsm", patch(base, tets + 4, "<I", 3),
                "3 columns, expected 4")
    # Nodes and links.
    rows_at, n, _, first = array_at(base, "NODE", 0)
    write_model("positions_rows_huge.fsm", patch(base, rows_at, "<I", 2**31 - 1), "truncated")
    write_model("position_nan.fsm", patch(base, first, "<d", math.nan), "node 0")
    _, _, _, masses = array_at(base, "NODE", 3)
    write_model("mass_negative.fsm", patch(base, masses, "<d", -1.0), "mass -1 kg must be positive")
    write_model("mass_zero.fsm", patch(base, masses + 8, "<d", 0.0), "must be positive")
    _, _, _, radii = array_at(base, "NODE", 4)
    write_model("radius_negative.fsm", patch(base, radii, "<d", -0.002), "radius")
    write_model("radius_infinite.fsm", patch(base, radii, "<d", math.inf), "radius")
    _, _, _, regions = array_at(base, "NODE", 5)
    write_model("node_region_out_of_range.fsm", patch_i32(base, regions, 40), "region")
    _, _, _, fixed = array_at(base, "NODE", 6)
    write_model("fixed_flag_two.fsm", patch(base, fixed, "<B", 2), "fixed flag must be 0 or 1")
    velocities_rows, _, _, _ = array_at(base, "NODE", 1)
    write_model("velocity_rows_disagree.fsm", patch(base, velocities_rows, "<I", n - 1),
                "malformed")
    _, _, _, links = array_at(base, "LINK", 0)
    write_model("link_node_out_of_range.fsm", patch_i32(base, links, 100000),
                "node index out of range")
    write_model("link_node_negative.fsm", patch_i32(base, links + 4, -3), "node index out of range")
    write_model("link_to_itself.fsm", patch_i32(base, links + 4, struct.unpack_from(
        "<i", base, links)[0]), "links a node to itself")
    _, _, _, stiffness = array_at(base, "LINK", 2)
    write_model("link_stiffness_nan.fsm", patch(base, stiffness, "<d", math.nan), "link 0")
    # Framing.
    _, _, regn, _ = section(base, "REGN")
    write_model("region_count_huge.fsm", patch(base, regn, "<I", 2**32 - 1), "truncated")
    write_model("region_name_length_huge.fsm", patch(base, regn + 4, "<I", 2**32 - 2), "truncated")
    _, _, meta, _ = section(base, "META")
    write_model("meta_string_length_huge.fsm", patch(base, meta, "<I", 2**31), "truncated")
    _, hdr, _, _ = section(base, "LINK")
    write_model("section_length_huge.fsm", refresh(set_section_length(base, "LINK", 2**63)),
                "truncated")
    dup = bytearray(base)
    s = section(base, "ATCH")
    dup += base[s[1]:s[2] + s[3]]
    write_model("section_twice.fsm", refresh(bytes(dup)), "appears twice")
    missing = bytearray(base)
    s = section(base, "TETS")
    del missing[s[1]:s[2] + s[3]]
    write_model("section_missing_v2.fsm", refresh(bytes(missing)), "the section is missing")
    renamed = bytearray(base)
    renamed[section(base, "NODE")[1]:section(base, "NODE")[1] + 4] = b"NOPE"
    write_model("section_renamed.fsm", refresh(bytes(renamed)), "section 'NODE'")
    # Header.
    write_model("empty.fsm", b"", "empty file")
    write_model("magic_wrong.fsm", b"PK\x03\x04" + base[4:], "not an fsm model file")
    write_model("version_zero.fsm", refresh(base[:8] + struct.pack("<I", 0) + base[12:]),
                "format version 0 does not exist")
    write_model("version_five.fsm", refresh(base[:8] + struct.pack("<I", 5) + base[12:]),
                "is newer than this runtime")
    write_model("version_2_32_minus_1.fsm",
                refresh(base[:8] + struct.pack("<I", 2**32 - 1) + base[12:]),
                "is newer than this runtime")
    write_model("required_flag.fsm", refresh(base[:12] + struct.pack("<I", 1) + base[16:]),
                "does not support")
    write_model("truncated_header.fsm", base[:20], "truncated")
    write_model("truncated_payload.fsm", base[:len(base) // 2], "truncated")
    write_model("payload_crc_wrong.fsm", base[:-1] + bytes([base[-1] ^ 0x55]), "corrupt: CRC-32")
    write_model("trailing_bytes.fsm", base + b"xyz", "unexpected bytes after the payload")
    header_crc = bytearray(base)
    header_crc[28] ^= 1
    write_model("header_crc_wrong.fsm", bytes(header_crc), "CRC-32 of the header")


# ---- Scenes -----------------------------------------------------------------------------------

MATERIAL = {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26}


def scene(**top):
    s = {"format": "fsm-scene", "version": 1, "units": "mm",
         "parts": [{"name": "block", "mesh": "../box.off", "topology": "tetrahedral",
                    "radius": 4, "material": dict(MATERIAL)}],
         "fixed": [{"part": "block", "plane": {"point": [0, 0, 0.5], "normal": [0, 0, 1]}}]}
    s.update(top)
    return s


def part(**kw):
    p = {"name": "block", "mesh": "../box.off", "topology": "tetrahedral", "radius": 4,
         "material": dict(MATERIAL)}
    p.update(kw)
    return p


def write_scene(name, content, words):
    path = HERE / "scene" / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    expect(path, words)


def scenes():
    # Values that escape the parser.
    write_scene("radius_1e999.json", json.dumps(scene()).replace('"radius": 4', '"radius": 1e999'),
                "number overflow")
    write_scene("radius_inf_token.json", json.dumps(scene()).replace('"radius": 4', '"radius": inf'),
                "not valid JSON")
    write_scene("radius_nan_token.json", json.dumps(scene()).replace('"radius": 4', '"radius": NaN'),
                "not valid JSON")
    write_scene("radius_zero.json", scene(parts=[part(radius=0)]), "'radius' must be positive")
    write_scene("radius_negative.json", scene(parts=[part(radius=-2)]), "'radius' must be positive")
    write_scene("radius_string.json", scene(parts=[part(radius="4")]), "must be a number")
    write_scene("version_2_32_plus_1.json", scene(version=2**32 + 1), "is newer than this builder")
    write_scene("version_2_64_minus_1.json", scene(version=2**64 - 1), "is newer than this builder")
    write_scene("version_negative.json", scene(version=-(2**32) + 1), "outside [1, 1]")
    write_scene("version_zero.json", scene(version=0), "outside [1, 1]")
    write_scene("version_fraction.json", scene(version=1.5), "'version' must be an integer")
    write_scene("version_string.json", scene(version="1"), "'version' must be an integer")
    write_scene("version_missing.json", {k: v for k, v in scene().items() if k != "version"},
                "missing 'version'")
    write_scene("format_wrong.json", scene(format="fsm"), "'format' must be")
    write_scene("vertex_index_2_32.json",
                scene(fixed=[{"part": "block", "vertices": [2**32]}]), "outside [0, 2147483647]")
    write_scene("vertex_index_negative.json",
                scene(fixed=[{"part": "block", "vertices": [-1]}]), "outside [0, 2147483647]")
    write_scene("vertex_index_beyond_part.json",
                scene(fixed=[{"part": "block", "vertices": [100000]}]), "out of range")
    write_scene("unknown_key.json", scene(colour="red"), "unknown key 'colour'")
    write_scene("unknown_part_key.json", scene(parts=[part(colour="red")]), "unknown key 'colour'")
    write_scene("parts_empty.json", scene(parts=[]), "'parts' must be a non-empty list")
    write_scene("parts_not_list.json", scene(parts={"a": 1}), "'parts' must be a non-empty list")
    write_scene("duplicate_part.json", scene(parts=[part(), part()]), "already exists")
    write_scene("mesh_missing.json", scene(parts=[part(mesh="nowhere.obj")]), "does not exist")
    write_scene("mesh_is_folder.json", scene(parts=[part(mesh="..")]), "not a regular file")
    write_scene("topology_unknown.json", scene(parts=[part(topology="cube")]), "unknown topology")
    write_scene("material_negative_modulus.json",
                scene(parts=[part(material={"density": 1050, "youngs_modulus": -5})]),
                "youngs_modulus")
    write_scene("material_zero_density.json",
                scene(parts=[part(material={"density": 0, "youngs_modulus": 5})]), "density")
    write_scene("attachment_to_itself.json",
                scene(attachments=[{"parts": ["block", "block"], "tolerance": 1}]),
                "to itself")
    write_scene("attachment_unknown_part.json",
                scene(attachments=[{"parts": ["block", "liver"], "tolerance": 1}]),
                "names part 'liver'")
    write_scene("fixed_two_kinds.json",
                scene(fixed=[{"part": "block", "vertices": [0],
                              "chain_end": "first"}]), "give exactly one of")
    write_scene("fixed_plane_zero_normal.json",
                scene(fixed=[{"part": "block", "plane": {"point": [0, 0, 0],
                                                         "normal": [0, 0, 0]}}]),
                "normal' is zero")
    write_scene("fixed_box_inverted.json",
                scene(fixed=[{"part": "block", "box": {"min": [1, 1, 1], "max": [0, 0, 0]}}]),
                "'max' is below 'min'")
    write_scene("chain_end_on_tetrahedral.json",
                scene(fixed=[{"part": "block", "chain_end": "last"}]),
                "'chain_end' applies to axis parts only")
    write_scene("not_fixed.json", scene(fixed=[]), "is neither fixed nor attached")
    write_scene("truncated.json", json.dumps(scene())[:-20], "not valid JSON")
    write_scene("not_an_object.json", "[1, 2, 3]", "must be a JSON object")
    write_scene("deeply_nested.json", "[" * 20000 + "]" * 20000, "must be a JSON object")
    write_scene("binary_garbage.json", "\x00\x89PNG\r\n\x1a\n", "not valid JSON")
    write_scene("limits_negative.json", scene(limits={"spheres": -1}), "must be positive")
    write_scene("limits_unknown_key.json", scene(limits={"cpus": 4}), "unknown key 'cpus'")
    # Resource exhaustion: refused by the budget before any work, with the estimate.
    write_scene("radius_tiny.json", scene(parts=[part(radius=0.001)]),
                "would need about")
    write_scene("metric_size_tiny.json",
                scene(parts=[part(metric={"type": "isotropic", "size": 0.0005})]),
                "would need about")
    write_scene("graded_size_tiny.json",
                scene(parts=[part(metric={"type": "graded", "size_min": 0.0001,
                                          "size_max": 0.01, "centre": [10, 10, 5],
                                          "distance": 20})]),
                "would need about")
    write_scene("graded_plateau_radius_negative.json",
                scene(parts=[part(metric={"type": "graded", "size_min": 2, "size_max": 4,
                                          "centre": [10, 10, 5], "distance": 5,
                                          "plateau_radius": -1})]),
                "graded plateau_radius must be non-negative")
    write_scene("anisotropic_size_tiny.json",
                scene(parts=[part(metric={"type": "anisotropic", "sizes": [0.001, 4, 4]})]),
                "would need about")
    write_scene("grid_spacing_tiny.json",
                scene(parts=[part(topology="grid", grid={"spacing": 0.001})]),
                "would need about")
    write_scene("packing_radius_tiny.json",
                scene(parts=[part(topology="packing", packing={"radius_min": 0.0005})]),
                "would need about")
    write_scene("axis_spacing_tiny.json",
                scene(parts=[part(topology="axis", axis={"spacing": 0.00001})],
                      fixed=[{"part": "block", "chain_end": "first"}]),
                "would need about")
    write_scene("alpha_wrap_tiny.json",
                scene(parts=[part(repair={"alpha_wrap": {"alpha": 0.0001, "offset": 0.00001}})]),
                "the alpha wrap would need about")
    write_scene("coordinate_scale_enormous.json",
                scene(mesh_units="m", parts=[part(radius=2)]), "would need about")
    write_scene("limits_below_the_model.json", scene(limits={"spheres": 5}),
                "more than the limit of 5")
    # A radius larger than the part: builds, with a warning.
    write_scene("radius_larger_than_part.json", scene(parts=[part(radius=9)]),
                "warning: larger than half the part's size")


# ---- Meshes -----------------------------------------------------------------------------------

def write_mesh(name, data, words):
    path = HERE / "mesh" / name
    path.write_bytes(data.encode() if isinstance(data, str) else data)
    expect(path, words)


TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def meshes():
    write_mesh("obj_nan.obj", TRI.replace("v 1 0 0", "v 1 nan 0"), "line 2: y coordinate 'nan'")
    write_mesh("obj_inf.obj", TRI.replace("v 1 0 0", "v 1 0 inf"), "line 2: z coordinate 'inf'")
    write_mesh("obj_1e999.obj", TRI.replace("v 1 0 0", "v 1e999 0 0"),
               "line 2: x coordinate '1e999' is not finite")
    write_mesh("obj_missing_coordinate.obj", TRI.replace("v 0 1 0", "v 0 1"),
               "line 3: vertex 3 has 2 coordinates")
    write_mesh("obj_word.obj", TRI.replace("v 0 0 1", "v 0 zero 1"), "line 4: y coordinate 'zero'")
    write_mesh("obj_face_missing_vertex.obj", TRI + "f 1 2 9\n",
               "line 9: face refers to vertex 9, but the file has 4 vertices")
    write_mesh("obj_face_index_zero.obj", TRI + "f 0 1 2\n", "line 9: face vertex '0'")
    write_mesh("obj_face_too_far_back.obj", TRI + "f -1 -2 -9\n", "counts back past the first")
    write_mesh("obj_face_two_vertices.obj", TRI + "f 1 2\n", "line 9: face with 2 vertices")
    write_mesh("obj_face_huge_index.obj", TRI + "f 1 2 99999999999999999999\n",
               "line 9: face vertex")
    write_mesh("obj_no_faces.obj", "v 0 0 0\nv 1 0 0\n", "no faces")
    write_mesh("obj_empty.obj", "", "no faces")
    write_mesh("obj_binary.obj", bytes(range(256)) * 4, "no faces")
    off = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    write_mesh("off_header_wrong.off", off.replace("OFF", "FOO"),
               "line 1: the file does not start with 'OFF'")
    write_mesh("off_binary.off", off.replace("OFF", "OFF BINARY"), "binary OFF is not supported")
    write_mesh("off_4d.off", off.replace("OFF", "4OFF"), "the OFF variant '4OFF'")
    write_mesh("off_counts_huge.off", off.replace("4 4 0", "4000000000 4000000000 0"),
               "the header declares 4000000000 vertices and 4000000000 faces, more than")
    write_mesh("off_counts_negative.off", off.replace("4 4 0", "-4 4 0"),
               "the vertex count '-4'")
    write_mesh("off_counts_missing.off", "OFF\n4\n", "the counts line needs")
    write_mesh("off_face_arity_huge.off", off.replace("3 1 2 3", "2000000000 1 2 3"),
               "face 3 declares 2000000000 vertices, the line has 3 numbers")
    write_mesh("off_face_arity_two.off", off.replace("3 1 2 3", "2 1 2"),
               "not a vertex count of at least 3")
    write_mesh("off_face_out_of_range.off", off.replace("3 1 2 3", "3 1 2 9"),
               "face 3 refers to vertex 9, the file has 4")
    write_mesh("off_count_too_large.off", off.replace("4 4 0", "4 9 0"),
               "the file ends before face 4 (truncated, or the header's counts are wrong)")
    write_mesh("off_truncated.off", off[:-16], "truncated")
    write_mesh("off_vertex_nan.off", off.replace("0 0 1\n", "0 0 nan\n"), "z coordinate 'nan'")
    tris = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    pts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    binary = b"x".ljust(80, b" ") + struct.pack("<I", 4)
    for t in tris:
        binary += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *pts[i]) for i in t)
        binary += b"\0\0"
    write_mesh("stl_truncated.stl", binary[:-30],
               "binary STL: the header declares 4 facets (284 bytes), the file has 254 bytes")
    write_mesh("stl_count_huge.stl", binary[:80] + struct.pack("<I", 2**32 - 1) + binary[84:],
               "binary STL: the header declares 4294967295 facets")
    write_mesh("stl_nan.stl", binary[:84 + 12] + struct.pack("<f", math.nan) + binary[84 + 16:],
               "byte 96: facet 0 vertex 0 has a non-finite x coordinate")
    write_mesh("stl_tiny.stl", b"abc", "not an STL file: 3 bytes")
    ascii_stl = "solid t\n" + "".join(
        "facet normal 0 0 0\nouter loop\n" + "".join("vertex %g %g %g\n" % pts[i] for i in t) +
        "endloop\nendfacet\n" for t in tris) + "endsolid t\n"
    write_mesh("stl_ascii_no_endsolid.stl", ascii_stl.replace("endsolid t\n", ""),
               "the file ends without 'endsolid'")
    write_mesh("stl_ascii_two_vertices.stl", ascii_stl.replace("vertex 0 0 1\nendloop", "endloop", 1),
               "expected 'vertex'")
    write_mesh("stl_ascii_nan.stl", ascii_stl.replace("vertex 1 0 0", "vertex 1 -nan 0", 1),
               "y coordinate '-nan'")
    write_mesh("stl_ascii_cut_in_facet.stl", ascii_stl[:60], "line 5: a vertex has 1 coordinates")
    write_mesh("stl_ascii_cut_after_facet.stl", ascii_stl[:ascii_stl.index("endfacet") + 9],
               "the file ends without 'endsolid'")
    write_mesh("stl_ascii_cut_after_loop.stl", ascii_stl[:ascii_stl.index("endloop") + 8],
               "the file ends inside a facet (truncated)")
    ply = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
           "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
    write_mesh("ply_no_magic.ply", ply.replace("ply\n", "plx\n", 1), "does not start with 'ply'")
    write_mesh("ply_format_unknown.ply", ply.replace("ascii", "utf8"), "unknown PLY format 'utf8'")
    write_mesh("ply_no_end_header.ply", ply.replace("end_header\n", ""),
               "line 9: unknown header line '0' (is 'end_header' missing")
    write_mesh("ply_vertex_count_huge.ply", ply.replace("vertex 4", "vertex 4000000000"),
               "the header declares elements needing at least")
    write_mesh("ply_face_arity_huge.ply", ply.replace("3 1 2 3", "255 1 2 3"),
               "face 3 declares a list of 255 values, more than the 3 numbers left on its line")
    write_mesh("ply_element_without_properties.ply",
               ply.replace("element face 4\n", "element extra 5521555555555\nelement face 4\n"),
               "element 'extra' declares 5521555555555 instances but no properties")
    write_mesh("ply_element_line_extra_words.ply",
               ply.replace("element face 4\n", "element face 4 list uchar int\n"),
               "line 7: 'element face 4' is followed by 'list'")
    write_mesh("ply_no_face_element.ply", ply.replace("element face 4\n"
               "property list uchar int vertex_indices\n", "").rsplit("3 0 2 1", 1)[0],
               "no 'face' element")
    write_mesh("ply_no_xyz.ply", ply.replace("property float z\n", "property float w\n"),
               "no x, y and z properties")
    write_mesh("ply_face_no_indices.ply", ply.replace("vertex_indices", "corners"),
               "no 'vertex_indices' list")
    write_mesh("ply_index_out_of_range.ply", ply.replace("3 1 2 3", "3 1 2 30"),
               "face 3 refers to vertex 30, the file has 4")
    write_mesh("ply_index_negative.ply", ply.replace("3 1 2 3", "3 1 2 -3"),
               "vertex index -3.000000, not a non-negative integer")
    write_mesh("ply_extra_values.ply", ply.replace("0 1 0\n", "0 1 0 7\n"),
               "has more values than its properties")
    write_mesh("ply_type_unknown.ply", ply.replace("property float y", "property quad y"),
               "unknown property type 'quad'")
    write_mesh("ply_float_list_count.ply", ply.replace("list uchar int", "list float int"),
               "a list count must be an integer type")
    binary_header = ply.split("end_header\n")[0].replace("ascii", "binary_little_endian")
    data = (binary_header + "end_header\n").encode()
    for p in pts:
        data += struct.pack("<3f", *p)
    for t in tris:
        data += struct.pack("<B3i", 3, *t)
    write_mesh("ply_binary_truncated.ply", data[:-7],
               "face 3 declares a list of 3 values, more than the 5 bytes left")
    nan_data = bytearray(data)
    struct.pack_into("<f", nan_data, len(binary_header) + len("end_header\n") + 4, math.nan)
    write_mesh("ply_binary_nan.ply", bytes(nan_data), "vertex 0 has a non-finite y coordinate")
    huge_list = bytearray(data.replace(b"list uchar int", b"list uint int"))
    write_mesh("ply_binary_list_count_huge.ply",
               bytes(huge_list[:-(4 * 13)]) + struct.pack("<I3i", 2**31, 1, 2, 3) * 4,
               "declares a list of 2147483648 values")


if __name__ == "__main__":
    for d in ("model", "scene", "mesh"):
        (HERE / d).mkdir(exist_ok=True)
        for f in (HERE / d).iterdir():
            f.unlink()
    models()
    scenes()
    meshes()
    (HERE / "manifest.json").write_text(json.dumps(dict(sorted(MANIFEST.items())), indent=1) + "\n")
    print(len(MANIFEST), "malformed inputs")
