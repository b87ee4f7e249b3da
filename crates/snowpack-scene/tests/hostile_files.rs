//! Files a broken exporter (or a hostile modder) might hand us: each is made
//! here, and each must be refused with an error that names the file and what
//! is wrong, quickly, without a panic, a stack overflow or a hang.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use serde_json::{Value, json};
use snowpack_scene::Scene;
use snowpack_scene::gltf_file::{GltfFile, MAX_ACCESSOR_COUNT, MAX_DEPTH, MAX_NODES};

/// A fresh folder for one test, removed on drop.
struct Temp(PathBuf);

impl Temp {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("snowpack-hostile-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        Self(dir)
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs `f` on its own thread and fails the test if it takes more than a
/// generous bound (a hang must fail, not stall the suite).
fn within_seconds<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(20)).unwrap_or_else(|_| panic!("{what}: no answer within 20 s (a hang?)"))
}

/// A small skinned, animated glTF: one triangle on node 2, skinned to the
/// joints `root` (node 0) and its child `bone` (node 1), with a two-key
/// animation "Walk" moving the bone. Tests break one thing at a time.
struct Model {
    json: Value,
    bin: Vec<u8>,
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

impl Model {
    fn new() -> Self {
        let mut m = Self { json: json!({"asset": {"version": "2.0"}, "buffers": [], "bufferViews": [], "accessors": []}), bin: Vec::new() };
        let positions = m.accessor(&f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]), 5126, 3, "VEC3");
        m.json["accessors"][positions]["min"] = json!([0.0, 0.0, 0.0]);
        m.json["accessors"][positions]["max"] = json!([1.0, 0.0, 1.0]);
        let indices = m.accessor(&[0, 0, 1, 0, 2, 0], 5123, 3, "SCALAR");
        let joints = m.accessor(&[0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0], 5121, 3, "VEC4");
        let weights = m.accessor(&f32s(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), 5126, 3, "VEC4");
        let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let ibm = m.accessor(&f32s(&[identity, identity].concat()), 5126, 2, "MAT4");
        let times = m.accessor(&f32s(&[0.0, 1.0]), 5126, 2, "SCALAR");
        m.json["accessors"][times]["min"] = json!([0.0]);
        m.json["accessors"][times]["max"] = json!([1.0]);
        let moves = m.accessor(&f32s(&[0.0, 0.0, 0.0, 0.0, 0.5, 0.0]), 5126, 2, "VEC3");
        m.json["meshes"] = json!([{"name": "body", "primitives": [{
            "attributes": {"POSITION": positions, "JOINTS_0": joints, "WEIGHTS_0": weights}, "indices": indices
        }]}]);
        m.json["nodes"] = json!([
            {"name": "root", "children": [1]},
            {"name": "bone", "translation": [0.0, 1.0, 0.0]},
            {"name": "body", "mesh": 0, "skin": 0}
        ]);
        m.json["skins"] = json!([{"joints": [0, 1], "inverseBindMatrices": ibm}]);
        m.json["animations"] = json!([{"name": "Walk",
            "samplers": [{"input": times, "output": moves, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}]}]);
        m.json["scenes"] = json!([{"nodes": [0, 2]}]);
        m.json["scene"] = json!(0);
        m
    }

    /// Appends `bytes` (padded to 4) as a buffer view and an accessor over it; its index.
    fn accessor(&mut self, bytes: &[u8], component: u32, count: usize, kind: &str) -> usize {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let views = self.json["bufferViews"].as_array_mut().expect("views");
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        let view = views.len() - 1;
        let accessors = self.json["accessors"].as_array_mut().expect("accessors");
        accessors.push(json!({"bufferView": view, "componentType": component, "count": count, "type": kind}));
        accessors.len() - 1
    }

    /// Index of the accessor a mesh attribute (or "indices") uses.
    fn attribute(&self, name: &str) -> usize {
        let prim = &self.json["meshes"][0]["primitives"][0];
        let v = if name == "indices" { &prim["indices"] } else { &prim["attributes"][name] };
        v.as_u64().expect("accessor index") as usize
    }

    /// Overwrites bytes of the binary chunk where accessor `k`'s data starts (+ `at`).
    fn poke(&mut self, k: usize, at: usize, bytes: &[u8]) {
        let view = self.json["accessors"][k]["bufferView"].as_u64().expect("view") as usize;
        let start = self.json["bufferViews"][view]["byteOffset"].as_u64().expect("offset") as usize + at;
        self.bin[start..start + bytes.len()].copy_from_slice(bytes);
    }

    /// The `.glb` file: header, JSON chunk, BIN chunk.
    fn glb(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        json["buffers"] = json!([{"byteLength": self.bin.len()}]);
        let mut text = serde_json::to_vec(&json).expect("json");
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + text.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&text);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }

    fn write(&self, dir: &Path, name: &str) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, self.glb()).expect("write glb");
        path
    }
}

/// Every way this crate reads a glTF file, as the scene uses it: a terrain
/// mesh, an accumulation object, a character.
fn every_use(path: &Path) -> [Result<(), String>; 3] {
    let open = || GltfFile::open(path);
    [open().and_then(|g| g.world_triangles(1.0).map(drop)), open().and_then(|g| g.object_mesh(1.0).map(drop)), open().and_then(|g| g.skinned_model().map(drop))]
}

/// `model` written as `name`, refused by every use with a message naming the
/// file (when `open` refuses it) and containing `words`.
fn refused(dir: &Path, name: &str, model: &Model, words: &str) {
    let path = model.write(dir, name);
    let results = within_seconds(name, move || every_use(&path));
    for (use_, result) in ["terrain mesh", "object", "character"].iter().zip(results) {
        let err = result.err().unwrap_or_else(|| panic!("{name} as a {use_}: accepted"));
        assert!(err.contains(words), "{name} as a {use_}: {err:?} does not say {words:?}");
    }
    // Opening alone refuses what is wrong with the file itself.
    if let Err(err) = GltfFile::open(&dir.join(name)) {
        assert!(err.contains(name), "{name}: {err:?} does not name the file");
    }
}

#[test]
fn the_model_the_tests_break_loads_in_every_use() {
    let dir = Temp::new("good");
    let path = Model::new().write(&dir.0, "good.glb");
    for result in within_seconds("good", move || every_use(&path)) {
        result.expect("the unbroken model loads");
    }
}

#[test]
fn a_node_that_is_its_own_ancestor_is_refused_in_every_use() {
    let dir = Temp::new("cycle");
    let mut m = Model::new();
    m.json["nodes"][1]["children"] = json!([0]);
    refused(&dir.0, "cycle.glb", &m, "own ancestor");
    let mut m = Model::new();
    m.json["nodes"][1]["children"] = json!([1]);
    refused(&dir.0, "self.glb", &m, "own child");
    // A loop of three nodes that no scene reaches is refused all the same.
    let mut m = Model::new();
    m.json["nodes"].as_array_mut().expect("nodes").extend([json!({"children": [4]}), json!({"children": [5]}), json!({"children": [3]})]);
    refused(&dir.0, "deep-cycle.glb", &m, "own ancestor");
}

#[test]
fn a_node_with_two_parents_or_a_child_listed_as_a_root_is_refused() {
    let dir = Temp::new("parents");
    let mut m = Model::new();
    m.json["nodes"][2]["children"] = json!([1]);
    refused(&dir.0, "two-parents.glb", &m, "two parents");
    let mut m = Model::new();
    m.json["scenes"][0]["nodes"] = json!([0, 1, 2]);
    refused(&dir.0, "child-root.glb", &m, "as a root");
    let mut m = Model::new();
    m.json["scenes"][0]["nodes"] = json!([0, 2, 2]);
    refused(&dir.0, "twice.glb", &m, "twice");
}

#[test]
fn a_hierarchy_deeper_than_the_limit_is_refused() {
    let dir = Temp::new("depth");
    let mut m = Model::new();
    let nodes = m.json["nodes"].as_array_mut().expect("nodes");
    let first = nodes.len();
    for k in 0..MAX_DEPTH + 10 {
        nodes.push(json!({"children": [first + k + 1]}));
    }
    nodes.push(json!({}));
    m.json["nodes"][2]["children"] = json!([first]);
    refused(&dir.0, "deep.glb", &m, "levels deep");
}

#[test]
fn more_nodes_or_elements_than_the_limits_are_refused() {
    let dir = Temp::new("counts");
    let mut m = Model::new();
    m.json["nodes"].as_array_mut().expect("nodes").extend(std::iter::repeat_n(json!({}), MAX_NODES));
    refused(&dir.0, "many-nodes.glb", &m, "nodes; at most");
    let mut m = Model::new();
    let p = m.attribute("POSITION");
    m.json["accessors"][p]["count"] = json!(MAX_ACCESSOR_COUNT + 1);
    refused(&dir.0, "many-vertices.glb", &m, "at most");
}

#[test]
fn accessors_outside_their_buffers_or_empty_are_refused() {
    let dir = Temp::new("bounds");
    let mut m = Model::new();
    let p = m.attribute("POSITION");
    m.json["accessors"][p]["count"] = json!(1000);
    refused(&dir.0, "past-view.glb", &m, "run past the end");
    let mut m = Model::new();
    m.json["bufferViews"][0]["byteLength"] = json!(1 << 20);
    refused(&dir.0, "past-buffer.glb", &m, "past the end of buffer");
    let mut m = Model::new();
    m.json["accessors"][p]["byteOffset"] = json!(usize::MAX - 3);
    refused(&dir.0, "overflow.glb", &m, "run past the end");
    let mut m = Model::new();
    m.json["accessors"][p]["count"] = json!(0);
    refused(&dir.0, "empty.glb", &m, "no elements");
    let mut m = Model::new();
    m.json["bufferViews"][0]["byteStride"] = json!(4);
    refused(&dir.0, "stride.glb", &m, "stride");
    // Sparse values at an index past the accessor's elements.
    let mut m = Model::new();
    let idx = m.accessor(&[9, 0], 5123, 1, "SCALAR");
    let vals = m.accessor(&f32s(&[0.0, 0.0, 0.0]), 5126, 1, "VEC3");
    let (iv, vv) = (m.json["accessors"][idx]["bufferView"].clone(), m.json["accessors"][vals]["bufferView"].clone());
    m.json["accessors"][p]["sparse"] = json!({"count": 1, "indices": {"bufferView": iv, "componentType": 5123}, "values": {"bufferView": vv}});
    refused(&dir.0, "sparse.glb", &m, "sparse index 9");
}

#[test]
fn accessors_of_the_wrong_type_for_their_use_are_refused() {
    let dir = Temp::new("types");
    let mut m = Model::new();
    let p = m.attribute("POSITION");
    m.json["accessors"][p]["type"] = json!("VEC2");
    refused(&dir.0, "vec2-positions.glb", &m, "POSITION");
    let mut m = Model::new();
    let i = m.attribute("indices");
    m.json["accessors"][i]["componentType"] = json!(5120);
    refused(&dir.0, "signed-indices.glb", &m, "indices");
    let mut m = Model::new();
    let w = m.attribute("WEIGHTS_0");
    m.json["accessors"][w]["type"] = json!("VEC3");
    refused(&dir.0, "vec3-weights.glb", &m, "WEIGHTS_0");
}

#[test]
fn an_index_past_the_vertices_is_refused() {
    let dir = Temp::new("index");
    let mut m = Model::new();
    let i = m.attribute("indices");
    m.poke(i, 2, &7u16.to_le_bytes());
    refused(&dir.0, "index.glb", &m, "7");
}

#[test]
fn vertices_that_are_not_finite_are_refused() {
    let dir = Temp::new("nan");
    let mut m = Model::new();
    let p = m.attribute("POSITION");
    m.poke(p, 12, &f32::NAN.to_le_bytes());
    refused(&dir.0, "nan.glb", &m, "finite");
    // Finite in the file, infinite once placed by its node and scale.
    let mut m = Model::new();
    m.json["nodes"][0]["scale"] = json!([3e38, 3e38, 3e38]);
    m.json["nodes"][2]["scale"] = json!([3e38, 3e38, 3e38]);
    let path = m.write(&dir.0, "huge.glb");
    let g = GltfFile::open(&path).expect("the file itself is well formed");
    let err = g.world_triangles(10.0).expect_err("infinite terrain vertices");
    assert!(err.contains("finite"), "{err}");
    let err = g.object_mesh(10.0).expect_err("infinite object vertices");
    assert!(err.contains("finite"), "{err}");
    // A transform that overflows f32 in the document itself.
    let mut m = Model::new();
    m.json["nodes"][1]["translation"] = json!([1e39, 0.0, 0.0]);
    refused(&dir.0, "inf-node.glb", &m, "not finite");
}

#[test]
fn a_joint_outside_the_skin_or_missing_inverse_binds_are_refused() {
    let dir = Temp::new("skin");
    let mut m = Model::new();
    let j = m.attribute("JOINTS_0");
    m.poke(j, 4, &[5]);
    let path = m.write(&dir.0, "joint.glb");
    let err = GltfFile::open(&path).expect("opens").skinned_model().expect_err("joint 5 of 2");
    assert!(err.contains("joint 5"), "{err}");
    let mut m = Model::new();
    let ibm = m.json["skins"][0]["inverseBindMatrices"].as_u64().expect("ibm") as usize;
    m.json["accessors"][ibm]["count"] = json!(1);
    refused(&dir.0, "ibm.glb", &m, "1 matrices for 2 joints");
    let mut m = Model::new();
    m.poke(ibm, 0, &f32::INFINITY.to_le_bytes());
    let path = m.write(&dir.0, "ibm-inf.glb");
    let err = GltfFile::open(&path).expect("opens").skinned_model().expect_err("infinite matrix");
    assert!(err.contains("not finite"), "{err}");
}

#[test]
fn animation_keys_that_are_not_finite_or_go_back_or_miss_values_are_refused() {
    let dir = Temp::new("keys");
    let times = |m: &Model| m.json["animations"][0]["samplers"][0]["input"].as_u64().expect("input") as usize;
    let skinned = |m: &Model, name: &str| {
        let path = m.write(&dir.0, name);
        GltfFile::open(&path).and_then(|g| g.skinned_model().map(drop)).expect_err(name)
    };
    let mut m = Model::new();
    let t = times(&m);
    m.poke(t, 4, &f32::NAN.to_le_bytes());
    assert!(skinned(&m, "nan-time.glb").contains("finite"));
    let mut m = Model::new();
    let t = times(&m);
    m.poke(t, 4, &(-1.0f32).to_le_bytes());
    assert!(skinned(&m, "back-time.glb").contains("increasing"));
    let mut m = Model::new();
    let out = m.json["animations"][0]["samplers"][0]["output"].as_u64().expect("output") as usize;
    m.json["accessors"][out]["count"] = json!(1);
    refused(&dir.0, "values.glb", &m, "2 key times but 1 values");
    let mut m = Model::new();
    m.poke(out, 0, &f32::INFINITY.to_le_bytes());
    assert!(skinned(&m, "inf-value.glb").contains("not finite"));
}

/// Found by fuzzing (issue 34): the gltf crate validates an animation's
/// samplers but not its channels' targets, and unwrapped a misspelt `path`
/// (a panic in every build); a target node past the last did the same.
#[test]
fn animation_channels_with_an_unknown_path_or_node_are_refused() {
    let dir = Temp::new("targets");
    let mut m = Model::new();
    m.json["animations"][0]["channels"][0]["target"]["path"] = json!("rot\tion");
    refused(&dir.0, "path.glb", &m, "target path");
    let mut m = Model::new();
    m.json["animations"][0]["channels"][0]["target"]["node"] = json!(99);
    refused(&dir.0, "node.glb", &m, "targets node 99");
}

/// Found by fuzzing (issue 34): the gltf crate's own validation indexed a
/// primitive's `POSITION` accessor unchecked, a panic in every build when it
/// named an accessor past the last.
#[test]
fn a_position_accessor_past_the_last_is_refused() {
    let dir = Temp::new("position-index");
    let mut m = Model::new();
    m.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(40);
    refused(&dir.0, "position.glb", &m, "POSITION is accessor 40");
}

#[test]
fn truncated_and_garbage_files_are_refused() {
    let dir = Temp::new("garbage");
    let glb = Model::new().glb();
    std::fs::write(dir.0.join("cut.glb"), &glb[..glb.len() - 20]).expect("write");
    std::fs::write(dir.0.join("noise.glb"), (0..4000u32).map(|k| (k.wrapping_mul(2_654_435_761) >> 24) as u8).collect::<Vec<_>>()).expect("write");
    // Found by fuzzing (issue 34): a GLB header whose length is under its own
    // 12 bytes made the gltf crate subtract past zero (a panic in debug builds).
    for length in [0u32, 11] {
        let mut short = glb.clone();
        short[8..12].copy_from_slice(&length.to_le_bytes());
        std::fs::write(dir.0.join(format!("short-{length}.glb")), short).expect("write");
    }
    for name in ["cut.glb", "noise.glb", "short-0.glb", "short-11.glb"] {
        let err = GltfFile::open(&dir.0.join(name)).err().unwrap_or_else(|| panic!("{name} accepted"));
        assert!(err.contains(name), "{err}");
    }
}

/// A scene in `dir` with `body`, parsed (within the time bound).
fn scene(dir: &Path, body: &str) -> Result<Scene, snowpack_scene::SceneError> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, body).expect("write scene");
    within_seconds(body, move || Scene::load(&path))
}

/// A scene error that names the scene, `key`, and contains every one of `words`.
fn scene_refuses(dir: &Path, body: &str, key: &str, words: &[&str]) {
    let err = scene(dir, body).err().unwrap_or_else(|| panic!("accepted: {body}"));
    let text = err.to_string();
    assert!(text.contains("scene.toml"), "{text}");
    assert_eq!(err.key, key, "{text}");
    for w in words {
        assert!(text.contains(w), "{text} does not say {w:?}");
    }
}

#[test]
fn a_cyclic_gltf_is_refused_as_terrain_object_and_actor_naming_the_key() {
    let dir = Temp::new("scene-cycle");
    let mut m = Model::new();
    m.json["nodes"][1]["children"] = json!([0]);
    m.write(&dir.0, "loop.glb");
    let words = ["loop.glb", "own ancestor"];
    scene_refuses(&dir.0, "[terrain]\nkind = \"mesh\"\npath = \"loop.glb\"\n", "[terrain].path", &words);
    scene_refuses(&dir.0, "[[object]]\nname = \"o\"\nkind = \"gltf\"\nfile = \"loop.glb\"\n", "[[object]][0].file", &words);
    scene_refuses(&dir.0, "[[actor]]\nkind = \"gltf\"\nfile = \"loop.glb\"\n", "[[actor]][0].file", &words);
}

#[test]
fn numbers_that_overflow_f32_are_refused_naming_the_key() {
    let dir = Temp::new("f32");
    scene_refuses(&dir.0, "[window]\ncenter = [-1e39, 0.0]\n", "[window].center", &["out of range"]);
    scene_refuses(&dir.0, "[[actor]]\npath = [[0.0, 0.0, 0.0, 0.0], [-1e39, 0.0, 0.0, 1.0]]\n", "[[actor]][0].path[1]", &["out of range"]);
    scene_refuses(&dir.0, "[[actor]]\nposition = [0.0, 1e300, 0.0]\n", "[[actor]][0].position", &["out of range"]);
    scene_refuses(&dir.0, "[camera]\ntarget = [0.0, 0.0, 5e38]\n", "[camera].target", &["out of range"]);
}

#[test]
fn a_window_whose_texel_coordinates_overflow_i32_is_refused_naming_the_key() {
    let dir = Temp::new("texels");
    // Default window: 64 m over 1024 texels, 1/16 m a texel: i32 texels reach 1.3e8 m.
    scene_refuses(&dir.0, "[window]\ncenter = [2e8, 0.0]\n", "[window].center", &["texel", "32-bit"]);
    scene_refuses(&dir.0, "[window]\ncenter = [0.0, -1e11]\n", "[window].center", &["texel"]);
    let follow = "[[actor]]\npath = [[0.0, 0.0, 0.0, 0.0], [3e8, 0.0, 0.0, 10.0]]\n[window]\nfollow = \"actor:0\"\n";
    scene_refuses(&dir.0, follow, "[[actor]][0].path", &["follows", "texel"]);
    // Far but representable is fine, and so is a coarser grid reaching further.
    scene(&dir.0, "[window]\ncenter = [1e8, -1e8]\n").expect("1e8 m fits");
    scene(&dir.0, "[snow]\nextent_m = 1024.0\nresolution = 64\n[window]\ncenter = [2e8, 0.0]\n").expect("16 m texels reach 3e10 m");
}

/// CRC-32 (the PNG chunk checksum) of `bytes`.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 == 1 { (c >> 1) ^ 0xedb8_8320 } else { c >> 1 };
        }
    }
    !c
}

fn png16(path: &Path, w: u32, h: u32) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| image::Luma([(x * 300 + y * 7) as u16])).save(path).expect("png");
}

#[test]
fn heightmaps_of_the_wrong_kind_size_or_depth_are_refused() {
    let dir = Temp::new("heightmaps");
    let d = &dir.0;
    let terrain = |file: &str| format!("[terrain]\nkind = \"heightmap\"\npath = \"{file}\"\n");
    png16(&d.join("ok.png"), 4, 3);
    scene(d, &terrain("ok.png")).expect("a 16-bit grey PNG loads");
    image::GrayImage::from_fn(4, 3, |x, _| image::Luma([x as u8 * 60])).save(d.join("grey8.png")).expect("png");
    scene(d, &terrain("grey8.png")).expect("an 8-bit grey PNG loads");
    image::RgbImage::from_fn(4, 3, |x, _| image::Rgb([x as u8, 0, 0])).save(d.join("rgb.png")).expect("png");
    scene_refuses(d, &terrain("rgb.png"), "[terrain].path", &["rgb.png", "Rgb8", "greyscale"]);
    png16(&d.join("dot.png"), 1, 1);
    scene_refuses(d, &terrain("dot.png"), "[terrain].path", &["dot.png", "1x1"]);
    let side = snowpack::low_level::terrain::HEIGHTMAP_MAX_SIDE + 1;
    png16(&d.join("wide.png"), side, 2);
    scene_refuses(d, &terrain("wide.png"), "[terrain].path", &["wide.png", &format!("{side}x2")]);
    std::fs::write(d.join("text.png"), b"heights: 1 2 3\n").expect("write");
    scene_refuses(d, &terrain("text.png"), "[terrain].path", &["text.png", "not a PNG"]);
    let png = std::fs::read(d.join("ok.png")).expect("read");
    std::fs::write(d.join("cut.png"), &png[..png.len() - 30]).expect("write");
    scene_refuses(d, &terrain("cut.png"), "[terrain].path", &["cut.png"]);
    // A header that claims a vast image is refused from the header, quickly.
    let mut vast = png.clone();
    vast[16..20].copy_from_slice(&200_000u32.to_be_bytes());
    let crc = crc32(&vast[12..29]);
    vast[29..33].copy_from_slice(&crc.to_be_bytes());
    std::fs::write(d.join("vast.png"), &vast).expect("write");
    scene_refuses(d, &terrain("vast.png"), "[terrain].path", &["vast.png", "200000x3"]);
}

#[test]
fn hdr_skies_of_the_wrong_size_or_not_hdr_are_refused() {
    let dir = Temp::new("skies");
    let d = &dir.0;
    let light = |file: &str| format!("[light]\nenvironment = \"{file}\"\n");
    let write_hdr = |name: &str, w: u32, h: u32| {
        let pixels = vec![image::Rgb([0.5f32, 0.6, 0.7]); (w * h) as usize];
        let file = std::fs::File::create(d.join(name)).expect("create");
        image::codecs::hdr::HdrEncoder::new(file).encode(&pixels, w as usize, h as usize).expect("hdr");
    };
    write_hdr("ok.hdr", 64, 32);
    scene(d, &light("ok.hdr")).expect("a 64x32 sky loads");
    write_hdr("small.hdr", 8, 4);
    scene_refuses(d, &light("small.hdr"), "[light].environment", &["small.hdr", "8x4", "smaller"]);
    // Only a header, claiming an enormous image: refused before decoding.
    std::fs::write(d.join("vast.hdr"), b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n").expect("write");
    scene_refuses(d, &light("vast.hdr"), "[light].environment", &["vast.hdr", "200000x100000", "larger"]);
    std::fs::write(d.join("text.hdr"), b"a sky, honestly\n").expect("write");
    scene_refuses(d, &light("text.hdr"), "[light].environment", &["text.hdr", "Radiance"]);
    let bytes = std::fs::read(d.join("ok.hdr")).expect("read");
    std::fs::write(d.join("cut.hdr"), &bytes[..bytes.len() / 2]).expect("write");
    scene_refuses(d, &light("cut.hdr"), "[light].environment", &["cut.hdr"]);
}

/// Found while writing the fuzz targets (issue 34): a scene may name any
/// path, and `/dev/zero` read for ever (allocating as it went) and a named
/// pipe blocked the load until something wrote to it. Every file a scene
/// names, and the scene itself, must be a regular file, refused quickly
/// otherwise.
#[cfg(unix)]
#[test]
fn devices_and_pipes_are_refused_quickly_wherever_a_scene_names_a_file() {
    let dir = Temp::new("devices");
    let d = &dir.0;
    let fifo = d.join("pipe.glb");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status().expect("mkfifo runs");
    assert!(made.success(), "mkfifo {}", fifo.display());
    for file in ["/dev/zero", fifo.to_str().expect("utf-8 path")] {
        let uses = [
            (format!("[terrain]\nkind = \"mesh\"\npath = \"{file}\"\n"), "[terrain].path"),
            (format!("[terrain]\nkind = \"heightmap\"\npath = \"{file}\"\n"), "[terrain].path"),
            (format!("[[object]]\nname = \"o\"\nkind = \"gltf\"\nfile = \"{file}\"\n"), "[[object]][0].file"),
            (format!("[light]\nenvironment = \"{file}\"\n"), "[light].environment"),
        ];
        for (body, key) in uses {
            scene_refuses(d, &body, key, &[file, "not a regular file"]);
        }
        // A character is looked up first: not a file, so it does not exist as one.
        scene_refuses(d, &format!("[[actor]]\nkind = \"gltf\"\nfile = \"{file}\"\n"), "[[actor]][0].file", &[file]);
        let path = PathBuf::from(file);
        let err = within_seconds(file, move || Scene::load(&path)).expect_err("a device or a pipe as the scene file");
        assert!(err.to_string().contains("not a regular file"), "{err}");
        // A glTF file whose buffer is the device or the pipe.
        let mut m = Model::new();
        m.json["buffers"] = json!([{"byteLength": m.bin.len(), "uri": file}]);
        let text = serde_json::to_vec(&m.json).expect("json");
        std::fs::write(d.join("outside.gltf"), text).expect("write");
        let path = d.join("outside.gltf");
        let err = within_seconds("a buffer on a device", move || GltfFile::open(&path).err()).expect("refused");
        assert!(err.contains("not a regular file"), "{err}");
    }
}

/// Found by fuzzing (issue 34): an object metres across by the billion (a
/// glTF vertex at 1e30 m, or a box of 1e12 m, within what a scene accepts)
/// overflowed the texel size of its chart in the accumulation atlas: a panic
/// in a debug build, a wrapped tiny chart and rectangles outside the atlas in
/// release. Laid out now, every chart lies inside the atlas with its gutter.
#[test]
fn vast_objects_are_laid_out_inside_the_accumulation_atlas() {
    use snowpack::low_level::accumulate::AtlasLayout;
    use snowpack::low_level::accumulate::atlas::GUTTER;
    let dir = Temp::new("vast-objects");
    let mut m = Model::new();
    let p = m.attribute("POSITION");
    m.poke(p, 12, &1e30f32.to_le_bytes());
    m.write(&dir.0, "vast.glb");
    let body = "[[object]]\nname = \"mesh\"\nkind = \"gltf\"\nfile = \"vast.glb\"\n\n[[object]]\nname = \"box\"\nsize_m = [1e12, 1.0, 1.0]\n";
    let s = scene(&dir.0, body).expect("finite objects load");
    let objects: Vec<_> = s.objects.iter().map(snowpack_scene::ObjectSpec::object).collect();
    let resolution = 1024;
    let layout = within_seconds("atlas layout", move || AtlasLayout::new(&objects, resolution, 0.0625)).expect("vast objects still fit, coarsely");
    for c in &layout.charts {
        let [x, y, w, h] = c.rect;
        assert!(x >= GUTTER && y >= GUTTER, "chart {:?} starts inside its gutter", c.rect);
        assert!(u64::from(x) + u64::from(w) + u64::from(GUTTER) <= u64::from(resolution), "chart {:?} runs past the atlas", c.rect);
        assert!(u64::from(y) + u64::from(h) + u64::from(GUTTER) <= u64::from(resolution), "chart {:?} runs past the atlas", c.rect);
    }
}

/// Found by fuzzing (issue 34): a rotation key of (0, 0, 0, 1e-38), finite
/// but of a length whose square is 0 in f32, normalised to NaN, and the
/// character's NaN joints and feet reached the capture. Such keys and node
/// rotations are refused; a cubic spline between good keys that passes
/// through 0 (keys q and -q, flat tangents, halfway) poses the identity
/// rather than NaN.
#[test]
fn rotations_that_do_not_normalise_are_refused_and_splines_through_zero_stay_finite() {
    let dir = Temp::new("rotations");
    let add_rotation = |m: &mut Model, values: &[f32], interpolation: &str| {
        let times = m.json["animations"][0]["samplers"][0]["input"].clone();
        let out = m.accessor(&f32s(values), 5126, values.len() / 4, "VEC4");
        let samplers = m.json["animations"][0]["samplers"].as_array_mut().expect("samplers");
        samplers.push(json!({"input": times, "output": out, "interpolation": interpolation}));
        let sampler = samplers.len() - 1;
        let channels = m.json["animations"][0]["channels"].as_array_mut().expect("channels");
        channels.push(json!({"sampler": sampler, "target": {"node": 1, "path": "rotation"}}));
    };
    for (name, key) in [("tiny.glb", [0.0, 0.0, 0.0, 1e-38]), ("zero.glb", [0.0; 4]), ("vast.glb", [0.0, 0.0, 1e30, 1e30])] {
        let mut m = Model::new();
        add_rotation(&mut m, &[[0.0, 0.0, 0.0, 1.0], key].concat(), "LINEAR");
        let path = m.write(&dir.0, name);
        let err = GltfFile::open(&path).expect("opens").skinned_model().expect_err(name);
        assert!(err.contains("rotation key 1") && err.contains("not a rotation"), "{name}: {err}");
        let mut m = Model::new();
        m.json["nodes"][1]["rotation"] = json!(key);
        // A vast rotation already overflows the node's matrix.
        refused(&dir.0, &format!("node-{name}"), &m, if name == "vast.glb" { "not finite" } else { "not a rotation" });
    }

    let mut m = Model::new();
    let (flat, q, minus_q) = ([0.0; 4], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, -1.0]);
    add_rotation(&mut m, &[flat, q, flat, flat, minus_q, flat].concat(), "CUBICSPLINE");
    m.write(&dir.0, "spline.glb");
    let s = scene(&dir.0, "[[actor]]\nkind = \"gltf\"\nfile = \"spline.glb\"\nfeet = [\"bone\"]\nposition = [0.0, 0.0, 0.0]\n").expect("good keys load");
    let mut world = snowpack_scene::World::new(&s);
    for step in 0..8 {
        for c in world.characters() {
            assert!(c.joints.iter().chain(&c.nodes).all(|j| j.is_finite()), "step {step}: joints or nodes are not finite");
        }
        world.step(0.125);
    }
}

/// Found by fuzzing (issue 34): an object's UVs were read unchecked, so a NaN
/// texture coordinate reached the atlas (which charted around it) and a saved
/// scene no longer equalled itself. An object's `TEXCOORD_0` must be finite;
/// the terrain and characters do not read UVs.
#[test]
fn an_object_whose_uvs_are_not_finite_is_refused() {
    let dir = Temp::new("uvs");
    let mut m = Model::new();
    let uv = m.accessor(&f32s(&[0.0, 0.0, 1.0, f32::NAN, 0.0, 1.0]), 5126, 3, "VEC2");
    m.json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uv);
    let path = m.write(&dir.0, "uv.glb");
    let g = GltfFile::open(&path).expect("the file itself is well formed");
    let err = g.object_mesh(1.0).expect_err("a NaN UV");
    assert!(err.contains("TEXCOORD_0 1") && err.contains("not finite"), "{err}");
    g.world_triangles(1.0).expect("a terrain reads no UVs");
    scene_refuses(&dir.0, "[[object]]\nname = \"o\"\nkind = \"gltf\"\nfile = \"uv.glb\"\n", "[[object]][0].file", &["uv.glb", "TEXCOORD_0"]);
}
