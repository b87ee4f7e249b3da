//! Hostile files through the binary: `snowpack run` exits 2 naming the scene,
//! the key and the file at fault, within a few seconds, without a panic and
//! without writing any output.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::Temp;

/// Generous: refusing a file takes well under a second; a hang or a stack
/// overflow must fail here rather than stall the suite.
const LIMIT: Duration = Duration::from_secs(30);

/// `snowpack run --headless` on `scene`, killed (and the test failed) past `LIMIT`.
fn run_bounded(scene: &Path, out: &Path) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_snowpack"))
        .env("SNOWPACK_LOG", "error")
        .args(["run", "--headless", "--frames", "2", "--scene"])
        .arg(scene)
        .arg("--out")
        .arg(out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start snowpack");
    let start = Instant::now();
    loop {
        if child.try_wait().expect("poll snowpack").is_some() {
            return child.wait_with_output().expect("snowpack's output");
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let output = child.wait_with_output().expect("snowpack's output");
            panic!("{}: still running after {LIMIT:?}: {}", scene.display(), String::from_utf8_lossy(&output.stderr));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The scene `body` in `dir` exits 2 with a message naming the scene file,
/// `key` and every one of `words`, and writes nothing.
fn exits_2(dir: &Path, name: &str, body: &str, key: &str, words: &[&str]) {
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(&scene, body).expect("write scene");
    let out = dir.join(format!("{name}-out"));
    let output = run_bounded(&scene, &out);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{name}: exit {:?}: {stderr}", output.status);
    assert!(stderr.contains(&format!("{name}.toml")) && stderr.contains(key), "{name}: {stderr} does not name the scene and {key}");
    for w in words {
        assert!(stderr.contains(w), "{name}: {stderr} does not say {w:?}");
    }
    assert!(!stderr.contains("panicked"), "{name}: {stderr}");
    assert!(!out.join("meta.json").exists() && !out.join("snow.npy").exists(), "{name}: output written for a bad scene");
}

/// A one-triangle `.glb` whose nodes 0 and 1 are each other's child: the
/// file a broken exporter wrote that used to overflow the stack (terrain)
/// and hang (object).
fn cyclic_glb() -> Vec<u8> {
    let positions: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0].iter().flat_map(|x| x.to_le_bytes()).collect();
    let json = r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":36}],"bufferViews":[{"buffer":0,"byteLength":36}],
"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
"nodes":[{"name":"a","mesh":0,"children":[1]},{"name":"b","children":[0]}],"scenes":[{"nodes":[0]}],"scene":0}"#;
    let mut text = json.as_bytes().to_vec();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + positions.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(text.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&text);
    glb.extend_from_slice(&(positions.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&positions);
    glb
}

#[test]
fn a_cyclic_gltf_exits_2_as_a_terrain_mesh_an_object_and_an_actor() {
    let dir = Temp::new("hostile-cycle");
    std::fs::write(dir.0.join("loop.glb"), cyclic_glb()).expect("write glb");
    let words = ["loop.glb", "own ancestor"];
    exits_2(&dir.0, "terrain", "[terrain]\nkind = \"mesh\"\npath = \"loop.glb\"\n", "[terrain].path", &words);
    exits_2(&dir.0, "object", "[[object]]\nname = \"o\"\nkind = \"gltf\"\nfile = \"loop.glb\"\n", "[[object]][0].file", &words);
    exits_2(&dir.0, "actor", "[[actor]]\nkind = \"gltf\"\nfile = \"loop.glb\"\n", "[[actor]][0].file", &words);
}

#[test]
fn numbers_infinite_as_f32_or_beyond_the_texel_grid_exit_2() {
    let dir = Temp::new("hostile-numbers");
    exits_2(&dir.0, "center", "[window]\ncenter = [-1e39, 0.0]\n", "[window].center", &["out of range"]);
    exits_2(&dir.0, "path", "[[actor]]\npath = [[-1e39, 0.0, 0.0, 0.0]]\n", "[[actor]][0].path[0]", &["out of range"]);
    exits_2(&dir.0, "texels", "[window]\ncenter = [0.0, 5e9]\n", "[window].center", &["texel"]);
}
