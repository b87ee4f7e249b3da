//! Any bytes as a `[terrain] kind = "heightmap"` PNG: refused naming the
//! scene, the file and `[terrain].path`, or loaded with one finite height
//! per pixel within `0..=height_scale_m`, that reads back the same when
//! written as a 16-bit PNG (a round trip of the reader's orientation and
//! scale), and whose world is built and stepped.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use snowpack::TerrainSource;
use snowpack::low_level::HeightmapTerrainExt;

/// `height_scale_m` of the fuzzed scene.
const SCALE_M: f32 = 10.0;

fuzz_target!(|data: &[u8]| {
    let dir = common::scratch("heightmap");
    std::fs::write(dir.join("height.png"), data).expect("write height.png");
    let body = format!("[terrain]\nkind = \"heightmap\"\npath = \"height.png\"\nheight_scale_m = {SCALE_M:?}\nsize_m = [40.0, 30.0]\n");
    let scene = match common::load(&dir, &body) {
        Ok(scene) => scene,
        Err(err) => return common::assert_names(&err, "height.png", "[terrain].path"),
    };
    let TerrainSource::Heightmap(map) = &scene.terrain else { panic!("a heightmap scene gave {:?}", scene.terrain) };
    let (w, h) = (map.width(), map.height());
    let heights = map.heights_m();
    assert_eq!(heights.len() as u64, u64::from(w) * u64::from(h));
    assert!(heights.iter().all(|v| (0.0..=SCALE_M).contains(v)), "a height outside 0..={SCALE_M} m");

    // Written back as the 16-bit grey PNG the docs ask for (image row 0 at
    // the far edge, +z), it loads as the same heights.
    let grey = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        let v = heights[((h - 1 - y) * w + x) as usize];
        image::Luma([(v / SCALE_M * 65535.0).round() as u16])
    });
    grey.save(dir.join("again.png")).expect("write again.png");
    let again = common::load(&dir, &body.replace("height.png", "again.png")).expect("the heightmap written back loads");
    let TerrainSource::Heightmap(back) = &again.terrain else { panic!("not a heightmap") };
    assert_eq!((back.width(), back.height()), (w, h));
    for (k, (a, b)) in heights.iter().zip(back.heights_m()).enumerate() {
        assert!((a - b).abs() <= SCALE_M / 65535.0, "pixel {k}: {a} m read back as {b} m");
    }
    common::build_world(&scene, true);
});
