//! GPU memory of a default window (64 m at 1024²), per resource, as
//! `SnowDeformation::memory_bytes` reports it (and the runner's `meta.json`
//! `gpu_memory_bytes` sums). Prints the table; asserts what each technique
//! allocates per texel. The resident tiles of the default trail keeper are
//! printed and counted apart: their slot pool (225 slots of 32² texels, two
//! to four 4-byte planes: only the tiles the window partly covers, and a
//! few near it) is sized by the tile grid: snow and packed snow, a plane
//! more for the footprints of points and combined and one for snowfall.

use glam::DVec2;
use snowpack::low_level::SnowInspect;
use snowpack::{SnowDeformation, SnowParams, Technique, TerrainSource};
use snowpack_testkit::testing;

const MIB: f64 = 1024.0 * 1024.0;

/// Prints the table; returns the total without the resident tiles.
fn table(snow: &SnowDeformation, what: &str) -> u64 {
    let list = snow.memory_bytes();
    let total: u64 = list.iter().map(|(_, b)| b).sum();
    let window: u64 = list.iter().filter(|(n, _)| *n != "resident tiles").map(|(_, b)| b).sum();
    println!("{what}:");
    for (name, bytes) in &list {
        println!("  {name:<16} {bytes:>10} B  {:>7.3} MiB", *bytes as f64 / MIB);
    }
    println!("  {:<16} {window:>10} B  {:>7.3} MiB", "window", window as f64 / MIB);
    println!("  {:<16} {total:>10} B  {:>7.3} MiB", "total", total as f64 / MIB);
    window
}

fn bytes_of(snow: &SnowDeformation, name: &str) -> u64 {
    snow.memory_bytes().iter().find(|(n, _)| *n == name).map_or_else(|| panic!("no {name} in memory_bytes"), |(_, b)| *b)
}

#[test]
fn default_window_memory_per_technique() {
    let Some(ctx) = testing::gpu() else { return };
    let params = SnowParams::default();
    assert_eq!((params.extent_m, params.resolution, params.technique), (64.0, 1024, Technique::Depth));
    let texels = u64::from(params.resolution).pow(2);
    let terrain = TerrainSource::Flat { height_m: 0.0 };

    // One frame with a sphere: the capture makes its output on the first frame that writes it.
    let sphere = [snowpack::Deformer::Sphere { center: glam::Vec3::new(0.0, 0.3, 0.0), radius: 0.4 }];
    let mut depth = SnowDeformation::new(ctx, params.clone(), terrain.clone(), DVec2::ZERO).expect("depth window");
    depth.step(ctx, &sphere, 1.0 / 60.0).expect("a depth frame");
    let depth_total = table(&depth, "depth");
    // Per texel: the snow word 4 (persistent and displayed), capture 2
    // (the analytic shapes' 16-bit codes; the depth target is 1x1 until a
    // frame draws into it), packed snow 2 (snow with mass: two texels a word); no terrain copy (evaluated from its source), no
    // footprint buffer, no decal layer, no blur, displayed-height or normal
    // buffer (normals are computed where they are used).
    assert!(depth.memory_bytes().iter().all(|(name, _)| *name != "terrain" && *name != "surface"));
    assert_eq!(bytes_of(&depth, "snow"), 4 * texels);
    // The capture holds one output of 16 bits a texel: the shapes' codes
    // where compute ray casts them (GPUs), the depth target where they are
    // drawn (software adapters); the other is a stand-in of a few bytes.
    let capture = bytes_of(&depth, "capture") + bytes_of(&depth, "capture target");
    assert!((2 * texels + 2..=2 * texels + 4).contains(&capture), "capture {capture} bytes");
    assert_eq!(bytes_of(&depth, "stamps"), 4);
    assert_eq!(bytes_of(&depth, "decal layer"), 4);
    assert_eq!(bytes_of(&depth, "packed snow"), 2 * texels + 40, "two texels a word and the mass ledger's five counts");
    let per_texel = 4 + 2 + 2;
    assert!(depth_total >= per_texel * texels && depth_total <= per_texel * texels + 64 * 1024, "depth window {depth_total}");
    // The default keeps trails: a pool of 225 slots of 32² texels (128 edge
    // tiles, 65 for a diagonal step, 32 spare), two 4-byte planes for depth
    // without snowfall (snow, packed snow), and the small key table and
    // bookkeeping buffers: under 2 MiB.
    let ring = 225 * 32 * 32 * 4 * 2;
    let tiles = bytes_of(&depth, "resident tiles");
    assert!(tiles >= ring && tiles < ring + 64 * 1024 && tiles <= 2 << 20, "resident tiles {tiles}");

    let mut combined =
        SnowDeformation::new(ctx, SnowParams { technique: Technique::Combined, ..params.clone() }, terrain.clone(), DVec2::ZERO).expect("combined window");
    combined.step(ctx, &sphere, 1.0 / 60.0).expect("a combined frame");
    let combined_total = table(&combined, "combined");
    assert_eq!(bytes_of(&combined, "stamps"), 4 * texels);
    assert_eq!(combined_total - depth_total, 4 * texels - 4, "combined adds only the footprint buffer");
    // ... and the slots' footprint plane.
    assert_eq!(bytes_of(&combined, "resident tiles") - bytes_of(&depth, "resident tiles"), 225 * 32 * 32 * 4);
    assert!(bytes_of(&combined, "resident tiles") <= 3 << 20);
    // The budget, everything `gpu_memory_bytes` sums, trails kept: the
    // adoption issue's 8 MiB for depth and 12 for combined, each with the
    // 2 MiB of packed snow that snow with mass adds and the 0.88 MiB of the
    // slots' packed-snow plane that keeps a trail's mass when the window
    // moves on (its issue's budget: the depth window within 10 MiB; a slot
    // holding the snow as the window's word, deficit and packed snow in one
    // u32, would win the plane back: docs/PERFORMANCE.md).
    let all = |snow: &SnowDeformation| snow.memory_bytes().iter().map(|(_, b)| b).sum::<u64>();
    assert!(all(&depth) <= 10 << 20, "depth: {} bytes", all(&depth));
    assert!(all(&combined) <= 15 << 20, "combined: {} bytes", all(&combined));

    // Switching allocates what the new technique needs at the next frame, and keeps it.
    depth.set_technique(Technique::Points);
    depth.step(ctx, &[], 1.0 / 60.0).expect("points frame");
    assert_eq!(bytes_of(&depth, "stamps"), 4 * texels);
    depth.set_technique(Technique::Decals);
    depth.step(ctx, &[], 1.0 / 60.0).expect("decals frame");
    assert_eq!(bytes_of(&depth, "decal layer"), 4 * texels);
    depth.set_technique(Technique::Depth);
    depth.step(ctx, &[], 1.0 / 60.0).expect("depth frame");
    assert_eq!(table(&depth, "depth after points and decals"), depth_total + 8 * texels - 8);
}
