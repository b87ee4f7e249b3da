"""Writes mound.gltf + mound.bin, the mesh terrain of scenes/mound.toml:
y = 2.5 exp(-((x-10)^2 + (z+6)^2) / 120) + 0.04 x on a 48x48-cell grid over
64 m, and a terrace (top at 1.5 m, vertical walls to -1 m) over
x in [-20, -8], z in [4, 16]. Run: python3 make_mound.py"""
import json, math, struct

n, ext = 48, 64.0
pos, idx = [], []
for i in range(n + 1):
    for j in range(n + 1):
        x = -ext / 2 + ext * j / n
        z = -ext / 2 + ext * i / n
        pos.append((x, 2.5 * math.exp(-((x - 10) ** 2 + (z + 6) ** 2) / 120.0) + 0.04 * x, z))
for i in range(n):
    for j in range(n):
        a = i * (n + 1) + j
        b, c = a + 1, a + n + 1
        idx += [a, c, c + 1, a, c + 1, b]
top = len(pos)
corners = [(-20, 4), (-8, 4), (-8, 16), (-20, 16)]
pos += [(x, 1.5, z) for x, z in corners] + [(x, -1.0, z) for x, z in corners]
idx += [top, top + 2, top + 1, top, top + 3, top + 2]
for k in range(4):
    a0, a1 = top + k, top + (k + 1) % 4
    idx += [a0, a1, a1 + 4, a0, a1 + 4, a0 + 4]
pb = b"".join(struct.pack("<3f", *p) for p in pos)
ib = b"".join(struct.pack("<I", i) for i in idx)
lo = [min(p[k] for p in pos) for k in range(3)]
hi = [max(p[k] for p in pos) for k in range(3)]
doc = {
    "asset": {"version": "2.0", "generator": "snowpack scenes/assets/make_mound.py"},
    "scene": 0,
    "scenes": [{"nodes": [0]}],
    "nodes": [{"name": "ground", "mesh": 0}],
    "meshes": [{"name": "ground", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
    "buffers": [{"uri": "mound.bin", "byteLength": len(pb) + len(ib)}],
    "bufferViews": [
        {"buffer": 0, "byteOffset": 0, "byteLength": len(pb), "target": 34962},
        {"buffer": 0, "byteOffset": len(pb), "byteLength": len(ib), "target": 34963},
    ],
    "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": lo, "max": hi},
        {"bufferView": 1, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
    ],
}
with open("mound.gltf", "w") as f:
    json.dump(doc, f, indent=1)
with open("mound.bin", "wb") as f:
    f.write(pb + ib)
