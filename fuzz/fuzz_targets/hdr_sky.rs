//! Any bytes as a `[light] environment` Radiance HDR sky: the library's
//! decoder gives a map (its size within the limits, one finite, non-negative
//! texel per pixel) or an error; the scene agrees with it and names the scene,
//! the file and `[light].environment` when it refuses. A decoded sky written
//! back as HDR decodes to the same size and radiance (RGBE keeps 8 bits of
//! mantissa: within 1/128 of the brightest channel).
#![no_main]

use libfuzzer_sys::fuzz_target;
use snowpack::EnvironmentMap;
use snowpack::low_level::render::environment::{ENVIRONMENT_MAX_H, ENVIRONMENT_MAX_W};
use snowpack_scene::EnvironmentSpec;

mod common;

fuzz_target!(|data: &[u8]| {
    let decoded = EnvironmentMap::from_hdr(data);
    if let Ok(map) = &decoded {
        assert!(map.width <= ENVIRONMENT_MAX_W && map.height <= ENVIRONMENT_MAX_H, "{}x{} accepted", map.width, map.height);
        assert_eq!(map.texels.len() as u64, u64::from(map.width) * u64::from(map.height));
        assert!(map.texels.iter().flatten().all(|c| c.is_finite() && *c >= 0.0), "a texel that is not finite or negative");
        round_trip(map);
    }
    let dir = common::scratch("hdr_sky");
    std::fs::write(dir.join("sky.hdr"), data).expect("write sky.hdr");
    match (common::load(&dir, "[light]\nenvironment = \"sky.hdr\"\n"), decoded) {
        (Ok(scene), Ok(map)) => match &scene.render.environment {
            EnvironmentSpec::File(_, loaded) => assert!(**loaded == map, "the scene's sky differs from the decoder's"),
            other => panic!("a sky file gave {other:?}"),
        },
        (Err(err), Err(_)) => common::assert_names(&err, "sky.hdr", "[light].environment"),
        (Ok(_), Err(e)) => panic!("the scene took a sky the decoder refuses ({e})"),
        (Err(e), Ok(_)) => panic!("the scene refused a sky the decoder takes: {e}"),
    }
});

/// `map` encoded as HDR and decoded again: same size, same radiance to RGBE's precision.
fn round_trip(map: &EnvironmentMap) {
    // The encoder's domain: it writes nonsense (1.7e38) for values below about
    // 1e-30, which RGBE's exponent cannot reach anyway; they go in as black.
    let encodable = |t: &[f32; 4]| [t[0], t[1], t[2]].map(|c| if c < 1e-30 { 0.0 } else { c });
    let pixels: Vec<image::Rgb<f32>> = map.texels.iter().map(|t| image::Rgb(encodable(t))).collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes).encode(&pixels, map.width as usize, map.height as usize).expect("encode");
    let back = EnvironmentMap::from_hdr(&bytes).expect("a decoded sky, encoded again, decodes");
    assert_eq!((back.width, back.height), (map.width, map.height));
    for (k, (t, b)) in map.texels.iter().zip(&back.texels).enumerate() {
        let a = encodable(t);
        let tolerance = a.iter().fold(0.0f32, |m, c| m.max(*c)) / 128.0;
        assert!((0..3).all(|c| (a[c] - b[c]).abs() <= tolerance), "texel {k}: {a:?} read back as {b:?}");
    }
}
