"""Writes the seed corpus of the file fuzz targets (issue 34) into
fuzz/corpus/: gltf_model, heightmap, hdr_sky and scene_world; and
fuzz/scene.dict, the scene schema's words for the scene targets. Seeds are the
shipped assets (the fox, the built-in sky downscaled to 64x32, the scenes)
and small hand-made edge cases, and for share_message the largest messages
a peer may send (a digest and a want of MAX_KEYS keys, a presence of
MAX_DEFORMERS deformers), which libFuzzer's growth never reaches in a job, a few of them refused on purpose so the
fuzzer starts on both sides of each check. The crash inputs fuzzing found
are kept beside them (crash-*). Run from anywhere:
    python3 fuzz/make_seeds.py
Only the standard library; the output is the same on every run."""
import json, math, os, shutil, struct, zlib

FUZZ = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(FUZZ)
CORPUS = os.path.join(FUZZ, "corpus")


def put(target, name, data):
    folder = os.path.join(CORPUS, target)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


# ---------------------------------------------------------------- glTF


def f32s(v):
    return b"".join(struct.pack("<f", x) for x in v)


class Model:
    """A glTF document and its binary chunk, built an accessor at a time."""

    def __init__(self):
        self.json = {"asset": {"version": "2.0"}, "buffers": [], "bufferViews": [], "accessors": []}
        self.bin = b""

    def accessor(self, data, component, count, kind, **extra):
        offset = len(self.bin)
        self.bin += data + b"\0" * (-len(data) % 4)
        self.json["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": len(data)})
        self.json["accessors"].append(dict({"bufferView": len(self.json["bufferViews"]) - 1, "componentType": component, "count": count, "type": kind}, **extra))
        return len(self.json["accessors"]) - 1

    def glb(self):
        doc = dict(self.json, buffers=[{"byteLength": len(self.bin)}] if self.bin else [])
        text = json.dumps(doc, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        out = struct.pack("<I4s", len(text), b"JSON") + text
        if self.bin:
            out += struct.pack("<I4s", len(self.bin), b"BIN\0") + self.bin
        return b"glTF" + struct.pack("<II", 2, 12 + len(out)) + out


def skinned(rotation_type=5126, interpolation="LINEAR"):
    """A triangle skinned to two joints, "root" and "foot", with a walk that
    moves and turns the foot (the hostile-file tests' model, with a foot)."""
    m = Model()
    p = m.accessor(f32s([0, 0, 0, 1, 0, 0, 0, 0, 1]), 5126, 3, "VEC3", min=[0, 0, 0], max=[1, 0, 1])
    n = m.accessor(f32s([0, 1, 0] * 3), 5126, 3, "VEC3")
    i = m.accessor(struct.pack("<3H", 0, 1, 2), 5123, 3, "SCALAR")
    j = m.accessor(bytes([0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]), 5121, 3, "VEC4")
    w = m.accessor(f32s([1, 0, 0, 0, 0.5, 0.5, 0, 0, 1, 0, 0, 0]), 5126, 3, "VEC4")
    eye = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    ibm = m.accessor(f32s(eye * 2), 5126, 2, "MAT4")
    t = m.accessor(f32s([0, 0.5, 1]), 5126, 3, "SCALAR", min=[0], max=[1])
    per = 3 if interpolation == "CUBICSPLINE" else 1
    moves = m.accessor(f32s([0, 0, 0, 0, 0.2, 0.1, 0, 0, 0] * per), 5126, 3 * per, "VEC3")
    if rotation_type == 5126:
        turns = m.accessor(f32s([0, 0, 0, 1, 0, 0.38, 0, 0.92, 0, 0, 0, 1] * per), 5126, 3 * per, "VEC4")
    else:
        turns = m.accessor(struct.pack("<12h", 0, 0, 0, 32767, 0, 12000, 0, 30000, 0, 0, 0, 32767) * per, 5122, 3 * per, "VEC4", normalized=True)
    m.json["meshes"] = [{"name": "body", "primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "JOINTS_0": j, "WEIGHTS_0": w}, "indices": i}]}]
    m.json["nodes"] = [
        {"name": "root", "children": [1]},
        {"name": "foot", "translation": [0, 1, 0]},
        {"name": "body", "mesh": 0, "skin": 0},
    ]
    m.json["skins"] = [{"joints": [0, 1], "inverseBindMatrices": ibm}]
    m.json["animations"] = [{"name": "Walk", "samplers": [{"input": t, "output": moves, "interpolation": interpolation}, {"input": t, "output": turns, "interpolation": interpolation}],
                             "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}, {"sampler": 1, "target": {"node": 1, "path": "rotation"}}]}]
    m.json["scenes"] = [{"nodes": [0, 2]}]
    m.json["scene"] = 0
    return m


def grid(cells=4, size=8.0):
    """A static grid (positions, normals, UVs, u16 indices) under a scaled,
    turned node: a mesh terrain or an object."""
    m = Model()
    pos, uv, idx = [], [], []
    for r in range(cells + 1):
        for c in range(cells + 1):
            x, z = size * (c / cells - 0.5), size * (r / cells - 0.5)
            pos += [x, 0.3 * math.sin(x) * math.cos(z), z]
            uv += [c / cells, r / cells]
    for r in range(cells):
        for c in range(cells):
            a = r * (cells + 1) + c
            idx += [a, a + cells + 1, a + 1, a + 1, a + cells + 1, a + cells + 2]
    count = (cells + 1) ** 2
    p = m.accessor(f32s(pos), 5126, count, "VEC3", min=[min(pos[k::3]) for k in range(3)], max=[max(pos[k::3]) for k in range(3)])
    n = m.accessor(f32s([0, 1, 0] * count), 5126, count, "VEC3")
    t = m.accessor(f32s(uv), 5126, count, "VEC2")
    i = m.accessor(struct.pack(f"<{len(idx)}H", *idx), 5123, len(idx), "SCALAR")
    m.json["meshes"] = [{"name": "ground", "primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t}, "indices": i}]}]
    m.json["nodes"] = [{"name": "holder", "children": [1], "rotation": [0, 0.38268, 0, 0.92388], "scale": [2, 1, 2]}, {"name": "ground", "mesh": 0, "translation": [1, 0, 0]}]
    m.json["scenes"] = [{"nodes": [0]}]
    return m


def gltf_seeds():
    shutil.copyfile(os.path.join(REPO, "assets", "Fox.glb"), os.path.join(CORPUS, "gltf_model", "fox.glb"))
    put("gltf_model", "skinned.glb", skinned().glb())
    put("gltf_model", "skinned-cubic-i16-rotations.glb", skinned(5122, "CUBICSPLINE").glb())
    put("gltf_model", "grid.glb", grid().glb())
    # Edge cases: each breaks one check (refused), or reaches a rarer path.
    m = skinned()
    m.json["nodes"][1]["children"] = [0]
    put("gltf_model", "cycle.glb", m.glb())
    m = grid()
    first = len(m.json["nodes"])
    m.json["nodes"] += [{"children": [first + k + 1]} for k in range(130)] + [{"mesh": 0}]
    m.json["nodes"][1]["children"] = [first]
    put("gltf_model", "deep.glb", m.glb())
    m = grid()
    k = m.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    ix = m.accessor(struct.pack("<H", 3), 5123, 1, "SCALAR")
    vals = m.accessor(f32s([0, 2, 0]), 5126, 1, "VEC3")
    m.json["accessors"][k]["sparse"] = {"count": 1, "indices": {"bufferView": m.json["accessors"][ix]["bufferView"], "componentType": 5123}, "values": {"bufferView": m.json["accessors"][vals]["bufferView"]}}
    put("gltf_model", "sparse.glb", m.glb())
    m = grid()
    m.json["meshes"][0]["primitives"][0]["mode"] = 5
    m.json["meshes"][0]["primitives"].append({"attributes": {"POSITION": 0}})
    put("gltf_model", "strip-and-unindexed.glb", m.glb())
    m = grid()
    m.json["nodes"][1]["matrix"] = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3, 0, 0, 1]
    del m.json["nodes"][1]["translation"]
    m.json["accessors"][0]["count"] = 4194305
    put("gltf_model", "too-many-vertices.glb", m.glb())
    m = Model()
    m.json["scenes"] = [{"nodes": [0]}]
    m.json["nodes"] = [{"name": "empty"}]
    put("gltf_model", "no-mesh.gltf", json.dumps(dict(m.json, buffers=[]), indent=1))


# ---------------------------------------------------------------- PNG


def png(width, height, colour, depth, rows, interlace=0):
    """A PNG of `rows` (each a bytes of the packed samples), filter 0."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    raw = b"".join(b"\0" + r for r in rows)
    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, interlace)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


def heightmap_seeds():
    w, h = 8, 6
    grey16 = [b"".join(struct.pack(">H", (x * 8000 + y * 1500) % 65536) for x in range(w)) for y in range(h)]
    put("heightmap", "grey16-8x6.png", png(w, h, 0, 16, grey16))
    put("heightmap", "grey8-5x4.png", png(5, 4, 0, 8, [bytes(x * 60 + y for x in range(5)) for y in range(4)]))
    put("heightmap", "grey-alpha16-3x3.png", png(3, 3, 4, 16, [b"".join(struct.pack(">HH", x * 20000, 65535) for x in range(3)) for _ in range(3)]))
    put("heightmap", "grey4-4x2.png", png(4, 2, 0, 4, [bytes([0x0F, 0xA5]), bytes([0x5A, 0xF0])]))
    put("heightmap", "rgb8-4x3.png", png(4, 3, 2, 8, [bytes([y * 60, 0, 0]) + bytes(9) for y in range(3)]))
    put("heightmap", "dot-1x1.png", png(1, 1, 0, 16, [b"\x12\x34"]))
    vast = bytearray(png(w, h, 0, 16, grey16))
    vast[16:20] = struct.pack(">I", 200000)
    vast[29:33] = struct.pack(">I", zlib.crc32(bytes(vast[12:29])) & 0xFFFFFFFF)
    put("heightmap", "vast-header.png", bytes(vast))
    put("heightmap", "cut.png", png(w, h, 0, 16, grey16)[:-30])


# ---------------------------------------------------------------- HDR


def read_hdr(path):
    """Width, height and float RGB rows of a Radiance file (flat or new RLE)."""
    data = open(path, "rb").read()
    end = data.index(b"\n\n") + 2
    line_end = data.index(b"\n", end)
    _, height, _, width = data[end:line_end].split()
    width, height, at = int(width), int(height), line_end + 1
    rows = []
    for _ in range(height):
        if data[at:at + 2] == b"\x02\x02":
            at += 4
            channels = []
            for _ in range(4):
                out = bytearray()
                while len(out) < width:
                    n = data[at]
                    if n > 128:
                        out += bytes([data[at + 1]]) * (n - 128)
                        at += 2
                    else:
                        out += data[at + 1:at + 1 + n]
                        at += 1 + n
                channels.append(out)
            rgbe = list(zip(*channels))
        else:
            rgbe = [tuple(data[at + 4 * k:at + 4 * k + 4]) for k in range(width)]
            at += 4 * width
        rows.append([(0.0, 0.0, 0.0) if e == 0 else tuple(c * 2.0 ** (e - 136) for c in (r, g, b)) for r, g, b, e in rgbe])
    return width, height, rows


def rgbe(c):
    m = max(c)
    if m < 1e-32:
        return (0, 0, 0, 0)
    mant, exp = math.frexp(m)
    scale = mant * 256.0 / m
    return tuple(int(x * scale) for x in c) + (exp + 128,)


def write_hdr(width, height, rows, rle=True, header_size=None):
    out = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + (header_size or f"-Y {height} +X {width}").encode() + b"\n"
    for row in rows:
        px = [rgbe(c) for c in row]
        if not rle:
            out += b"".join(bytes(p) for p in px)
            continue
        out += bytes([2, 2, width >> 8, width & 255])
        for ch in range(4):
            vals = [p[ch] for p in px]
            k = 0
            while k < width:
                run = 1
                while k + run < width and run < 127 and vals[k + run] == vals[k]:
                    run += 1
                if run > 2:
                    out += bytes([128 + run, vals[k]])
                    k += run
                else:
                    lit = vals[k:k + min(128, width - k)]
                    n = 1
                    while n < len(lit) and not (n + 2 < len(lit) and lit[n] == lit[n + 1] == lit[n + 2]):
                        n += 1
                    out += bytes([n]) + bytes(lit[:n])
                    k += n
    return out


def hdr_seeds():
    w, h, rows = read_hdr(os.path.join(REPO, "assets", "spiaggia_di_mondello_1k.hdr"))
    f = 16
    small = [[tuple(sum(rows[y * f + dy][x * f + dx][c] for dy in range(f) for dx in range(f)) / (f * f) for c in range(3)) for x in range(w // f)] for y in range(h // f)]
    sw, sh = w // f, h // f
    put("hdr_sky", f"mondello-{sw}x{sh}.hdr", write_hdr(sw, sh, small))
    put("hdr_sky", f"mondello-{sw}x{sh}-flat.hdr", write_hdr(sw, sh, small, rle=False))
    put("hdr_sky", "mondello-8x4-too-small.hdr", write_hdr(8, 4, [r[:8] for r in small[:4]], rle=False))
    put("hdr_sky", "vast-header.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n")
    put("hdr_sky", "flipped.hdr", write_hdr(sw, sh, small, header_size=f"+Y {sh} +X {sw}"))
    put("hdr_sky", "cut.hdr", write_hdr(sw, sh, small)[:1500])


# ---------------------------------------------------------------- scenes


EDGE_SCENES = {
    "files.toml": """# Every kind of file a scene names, from the corpus of the other targets.
[snow]
extent_m = 16.0
resolution = 64

[terrain]
kind = "heightmap"
path = "../fuzz/corpus/heightmap/grey16-8x6.png"
height_scale_m = 2.0
size_m = [20.0, 12.0]
center = [1.0, -1.0]

[light]
environment = "../fuzz/corpus/hdr_sky/mondello-64x32.hdr"

[[object]]
name = "grid"
kind = "gltf"
file = "../fuzz/corpus/gltf_model/grid.glb"
position = [0.0, 1.0, 0.0]
velocity = [0.5, 0.0, 0.0]

[[object]]
name = "ball"
kind = "sphere"
size_m = [1.0, 1.0, 1.0]
spin_deg_per_s = [0.0, 30.0, 0.0]

[[actor]]
kind = "gltf"
file = "../fuzz/corpus/gltf_model/skinned.glb"
feet = ["foot"]
placement = "snow"
path = [[-2.0, 0.0, 0.0, 0.0], [2.0, 0.0, 1.0, 3.0]]

[snowfall]
rate_m_per_s = 0.01
atlas_resolution = 256

[sim]
frames = 4
dt_s = 0.05
""",
    "follow.toml": """[snow]
extent_m = 8.0
resolution = 128
technique = "decals"

[terrain]
kind = "noise"
seed = 9
amplitude_m = 1.5
wavelength_m = 6.0

[[actor]]
kind = "box"
size_m = [0.5, 0.3, 1.0]
rotation_deg = [0.0, 45.0, 0.0]
position = [0.0, 0.2, 0.0]
velocity = [3.0, 0.0, 1.0]

[[actor]]
kind = "sphere"
radius_m = 0.4
physics = true
position = [1.0, 3.0, 1.0]
velocity = [0.0, 0.0, -2.0]

[[actor]]
kind = "point"
scale_per_m = 2.0
path = [[0.0, 0.1, 0.0, 0.0]]

[window]
follow = "actor:0"

[[spawn]]
count = 40
radius_m = 0.3
seed = 11

[store]
keep = "memory"
""",
    "crowd.toml": """[snow]
extent_m = 4.0
resolution = 32

[[spawn]]
count = 1500
radius_m = 2.0
seed = 1

[sim]
frames = 3
dt_s = 0.5
""",
}


def scene_dictionary():
    """fuzz/scene.dict, the words of the scene schema for libFuzzer (-dict):
    tables, `key = ` at a line's start, the choices' values, a few numbers at
    the limits and the files the corpus can name. Read from the scene crate's
    sources, so it follows the schema."""
    import glob, re
    src = "".join(open(f).read() for f in sorted(glob.glob(os.path.join(REPO, "crates", "snowpack-scene", "src", "*.rs"))))
    keys = set(re.findall(r'\.(?:f32|positive|non_negative|u32_in|bool|vec2|vec3|string|strings|rows4|choice|table|tables)\w*\("([a-z_0-9]+)"', src))
    keys |= set(re.findall(r'err\("([a-z_0-9]+)"', src))
    tables = set(re.findall(r'root\.table\("([a-z_]+)"\)', src))
    arrays = set(re.findall(r'root\.tables\("([a-z_]+)"\)', src))
    values = {"builtin:fox", "builtin", "procedural", "actor:0", "camera"}
    for group in re.findall(r'&\[((?:"[a-z_:]+",?\s*)+)\]', src):
        values |= set(re.findall(r'"([a-z_:]+)"', group))
    words = [f"[{t}]\n" for t in sorted(tables)] + [f"[[{t}]]\n" for t in sorted(arrays)]
    words += [f"\n{k} = " for k in sorted(keys - tables - arrays)] + [f'"{v}"' for v in sorted(values)]
    words += [" = [", "0.0, ", "1e12", "-1e12", "3e38", "1e-38", "true", "false", "]\n"]
    words += ["../fuzz/corpus/gltf_model/grid.glb", "../fuzz/corpus/gltf_model/skinned.glb", "../fuzz/corpus/heightmap/grey16-8x6.png",
              "../fuzz/corpus/hdr_sky/mondello-64x32.hdr", "assets/mound.gltf", "../assets/Fox.glb"]

    def quoted(word):
        return '"' + "".join({"\\": "\\\\", '"': '\\"', "\n": "\\x0A"}.get(c, c) for c in word) + '"'
    header = ["# The words of the scene schema for scene_parse and scene_world (libFuzzer", "# -dict), written by fuzz/make_seeds.py from crates/snowpack-scene/src."]
    with open(os.path.join(FUZZ, "scene.dict"), "w") as f:
        f.write("\n".join(header + [quoted(w) for w in words]) + "\n")


def scene_seeds():
    for name in sorted(os.listdir(os.path.join(REPO, "scenes"))):
        if name.endswith(".toml"):
            shutil.copyfile(os.path.join(REPO, "scenes", name), os.path.join(CORPUS, "scene_world", name))
    for name, text in EDGE_SCENES.items():
        put("scene_world", name, text)


# ---------------------------------------------------------------- shared snow's messages

# replicate/message.rs: the header, the limits.
SHARE_HEADER = b"SNWP" + struct.pack("<H", 4)
MAX_KEYS = 4096
MAX_DEFORMERS = 256


def share_seeds():
    """The largest well-formed messages of each list kind: the work a relay
    does per byte is what these reach (issue 46)."""
    clock = open(os.path.join(CORPUS, "share_message", "seed-digest"), "rb").read()[7:55]
    keys = [(c - 32, r - 32) for r in range(64) for c in range(64)][:MAX_KEYS]
    digest = SHARE_HEADER + b"\x07" + clock + struct.pack("<H", len(keys))
    digest += b"".join(struct.pack("<qqQ", c, r, (c * 2654435761 + r * 40503) & (2**64 - 1)) for c, r in keys)
    put("share_message", "seed-digest-max", digest)
    want = SHARE_HEADER + b"\x08" + struct.pack("<H", len(keys)) + b"".join(struct.pack("<qq", c, r) for c, r in keys)
    put("share_message", "seed-want-max", want)
    presence = SHARE_HEADER + b"\x04" + struct.pack("<qqIH", -64, -64, 128, MAX_DEFORMERS)
    presence += b"".join(struct.pack("<dd", 0.5 * i, -0.25 * i) for i in range(MAX_DEFORMERS))
    put("share_message", "seed-presence-max", presence)
    put("share_message", "seed-presses", presses_seed())


def presses_seed():
    """A `Presses` message (kind 13) of one frame: a sphere swept a little
    and a treaded wheel rolling (replicate/presses.rs: words coded as
    zigzagged residuals from no prediction, byte-shuffled, raw deflate)."""
    import zlib

    f32 = lambda v: struct.unpack("<I", struct.pack("<f", v))[0]
    zig = lambda r: ((r << 1) ^ (0xFFFFFFFF if r & 0x80000000 else 0)) & 0xFFFFFFFF
    words = []
    for k in range(1):
        t = 10.0 + k / 30.0
        bits = struct.unpack("<Q", struct.pack("<d", t))[0]
        head = [bits & 0xFFFFFFFF, bits >> 32, 0, 0, 0, 0, 0, (-64) & 0xFFFFFFFF, 0xFFFFFFFF, (-64) & 0xFFFFFFFF, 0xFFFFFFFF,
                128, f32(-0.5), f32(1.5), f32(3.0), 0, 2]
        ball = [1, 1] + [f32(v) for v in (4.0 + 0.1 * k, 0.6, 4.0, 4.1 + 0.1 * k, 0.6, 4.0, 0.3)] + [0] * 17
        wheel = [3, 1] + [f32(v) for v in (5.0 + 0.1 * k, 0.5, 5.0, 1.0, 0.0, 0.0, 0.1 * k,
                                            4.9 + 0.1 * k, 0.5, 5.0, 1.0, 0.0, 0.0, 0.1 * k - 0.1,
                                            0.33, 0.14, 1.0, 0.1, 0.03, 0.4)] + [0] * 4
        for row in (head, ball, wheel):
            words.extend(zig(w) for w in row)
    raw = bytes(((w >> (8 * b)) & 0xFF) for b in range(4) for w in words)
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    frames = c.compress(raw) + c.flush()
    return SHARE_HEADER + b"\x0d" + struct.pack("<QBBI", 7, 1, 0, len(frames)) + frames


if __name__ == "__main__":
    # Files are overwritten, never removed: the crash inputs that fuzzing
    # found (named crash-*) sit beside the seeds.
    for target in ["gltf_model", "heightmap", "hdr_sky", "scene_world"]:
        os.makedirs(os.path.join(CORPUS, target), exist_ok=True)
    gltf_seeds()
    heightmap_seeds()
    hdr_seeds()
    scene_seeds()
    scene_dictionary()
    share_seeds()
