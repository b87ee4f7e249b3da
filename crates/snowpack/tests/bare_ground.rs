//! `depth_m = 0`: bare ground, where all the snow there is comes from the
//! snowfall. Nothing divides by the rest depth into a NaN, the snow grows at
//! the snowfall's rate, and a deformer pressing into it leaves bare ground.

use glam::{DVec2, Vec3};
use snowpack::Snowfall;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::SnowWindowUniformExt;
use snowpack::low_level::deform::display::{DisplayParams, DisplayPass};
use snowpack::low_level::deform::resources::DeformResources;
use snowpack::low_level::deform::snow_word;
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::GpuTimer;
use snowpack::low_level::gpu::read_buffer;
use snowpack::{Deformer, GpuContext, SnowDeformation, SnowParams, Technique, TerrainSource};
use snowpack_testkit::cpu;
use snowpack_testkit::testing;

const DT: f32 = 1.0 / 60.0;
const RES: usize = 64;
/// Window side (m): 6.25 cm texels.
const EXTENT_M: f32 = 4.0;
const GROUND_M: f32 = 0.25;

/// A sphere of 0.3 m at the window's centre, its bottom 0.2 m below the ground.
fn sphere() -> Deformer {
    Deformer::Sphere { center: Vec3::new(0.0, GROUND_M + 0.1, 0.0), radius: 0.3 }
}

/// Distance (m) of texel (i, j)'s centre from the window's centre (x, z).
fn from_centre(i: usize, j: usize) -> f32 {
    let texel = EXTENT_M / RES as f32;
    let c = |k: usize| (k as f32 + 0.5) * texel - EXTENT_M / 2.0;
    c(j).hypot(c(i))
}

fn bare_window(ctx: &GpuContext, technique: Technique, rate: f32) -> SnowDeformation {
    let fall = Snowfall { rate_m_per_s: rate, max_m: 1.0, ..Snowfall::default() };
    let params = SnowParams { extent_m: EXTENT_M, resolution: RES as u32, depth_m: 0.0, technique, snowfall: Some(fall), ..SnowParams::default() };
    SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: GROUND_M }, DVec2::ZERO).expect("a window on bare ground")
}

#[test]
fn snowfall_on_bare_ground_grows_at_its_rate_and_a_deformer_leaves_bare_ground() {
    let Some(ctx) = testing::gpu() else { return };
    let rate = 0.05;
    for technique in [Technique::Depth, Technique::Points, Technique::Combined] {
        let mut snow = bare_window(ctx, technique, 0.0);
        // First frame with no snowfall: no snow at all, and no NaN in the
        // displayed surface (its rims divide by the rest depth).
        snow.step(ctx, &[sphere()], DT).expect("frame");
        let (shown, normals) = snow.read_surface(ctx).expect("surface");
        assert!(shown.iter().all(|&h| h == GROUND_M), "{technique:?}: bare ground is not shown at the ground");
        assert!(normals.iter().flatten().all(|n| n.is_finite()));
        assert!(snow.read_snow(ctx).expect("snow").iter().all(|&h| h == GROUND_M));
        // Then it snows for 2 s with the sphere resting in the snow.
        let fall = Snowfall { rate_m_per_s: rate, max_m: 1.0, ..Snowfall::default() };
        snow.set_snowfall(Some(fall)).expect("snowfall");
        let frames = 120;
        for _ in 0..frames {
            snow.step(ctx, &[sphere()], DT).expect("frame");
        }
        snow.finish(ctx).expect("finish");
        let expected = rate * DT * frames as f32;
        assert!((snow.fallen_m() - expected).abs() < 1e-5, "{technique:?}: fallen {} m, expected {expected}", snow.fallen_m());
        let heights = snow.read_snow(ctx).expect("snow");
        let (shown, normals) = snow.read_surface(ctx).expect("surface");
        assert!(heights.iter().chain(&shown).all(|h| h.is_finite()) && normals.iter().flatten().all(|n| n.is_finite()), "{technique:?}: NaN in the snow");
        let (mut open, mut under) = (0, 0);
        for i in 0..RES {
            for j in 0..RES {
                let depth = heights[i * RES + j] - GROUND_M;
                let r = from_centre(i, j);
                // Away from the sphere (and from the points' footprints and rims): the snowfall, everywhere.
                if r > 2.2 * 0.3 {
                    assert!((depth - expected).abs() < 1e-5, "{technique:?}: texel ({i}, {j}) has {depth} m of snow, expected {expected}");
                    open += 1;
                }
                // Under the sphere (the capture reaches where it is below the ground; the points at its contact).
                let pressed = if technique == Technique::Points { r < 0.05 } else { r < 0.2 };
                if pressed {
                    assert_eq!(depth, 0.0, "{technique:?}: texel ({i}, {j}) under the sphere holds {depth} m of snow");
                    under += 1;
                }
            }
        }
        assert!(open > RES * RES / 2 && under > 0, "{technique:?}: {open} open texels, {under} under the sphere");
    }
}

#[test]
fn bare_ground_keeps_its_trench_through_the_tiles() {
    let Some(ctx) = testing::gpu() else { return };
    // The default memory keeper: XOR against a rest of terrain + 0 + fallen.
    let mut snow = bare_window(ctx, Technique::Depth, 0.05);
    for _ in 0..60 {
        snow.step(ctx, &[sphere()], DT).expect("frame");
    }
    let before = snow.read_snow(ctx).expect("snow");
    assert!(before.contains(&GROUND_M) && before.iter().any(|&h| h > GROUND_M + 0.04));
    snow.set_snowfall(None).expect("the snow stops");
    // Two ring widths out (the trench's slots go to other tiles) and back.
    for center in [DVec2::new(8.0, 0.0), DVec2::new(16.0, 0.0), DVec2::ZERO] {
        snow.set_center(center);
        for _ in 0..120 {
            snow.step(ctx, &[], DT).expect("frame");
        }
    }
    let stats = snow.tile_stats().expect("tiles are kept by default");
    assert!(stats.restored > 0 && stats.window_waits < 120, "{stats:?}");
    let after = snow.read_snow(ctx).expect("snow");
    let differ = before.iter().zip(&after).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} texels of bare ground and new snow changed after the round trip");
}

#[test]
fn rims_at_zero_depth_match_cpu_and_stay_finite() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("rims_at_zero_depth_match_cpu_and_stay_finite");
    let mut rng = testing::Rng::new(seed);
    // Combined: the window has a footprint buffer for the point rims.
    let params = SnowParams {
        extent_m: EXTENT_M,
        resolution: RES as u32,
        depth_m: 0.0,
        snowfall: Some(Snowfall::default()),
        technique: snowpack::Technique::Combined,
        ..SnowParams::default()
    };
    let terrain_src =
        TerrainSource::Noise(snowpack::NoiseTerrain { seed: rng.next_u64() as u32, base_m: 0.0, amplitude_m: 1.0, wavelength_m: rng.range(2.0, 10.0) });
    let res = DeformResources::new(&ctx.device, &ctx.queue, &params, &terrain_src);
    let n = RES * RES;
    // The ground the rim evaluates from the terrain's source, per texel.
    let terrain = cpu::window::ground_plane(&terrain_src, [0, 0], RES as u32, params.texel_m());
    // Half the texels bare (no snowfall yet: a rest depth of 0), half with some snow.
    let fallen: Vec<f32> = (0..n).map(|_| if rng.range(0.0, 1.0) < 0.5 { 0.0 } else { rng.range(0.001, 0.3) }).collect();
    let snow_words: Vec<u32> = fallen.iter().map(|f| if rng.range(0.0, 1.0) < 0.5 { 0 } else { snow_word::deficit_quanta(rng.range(0.0, *f)) }).collect();
    let snow: Vec<f32> = snow_words.iter().zip(&terrain).zip(&fallen).map(|((&w, t), f)| snow_word::column_height(w, *t, *f)).collect();
    let (low_m, high_m) = (-3.0_f32, 3.0_f32);
    let stamps: Vec<u32> = terrain
        .iter()
        .zip(&fallen)
        .map(|(t, f)| {
            let rest = t + f;
            let foot = cpu::stamp::quantise(rest - rng.range(-0.1, 0.4), low_m, high_m);
            let h = cpu::stamp::quantise(rest + rng.range(-0.2, 0.5), low_m, high_m).max(foot);
            (h << 16) | foot
        })
        .collect();
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow_words));
    ctx.queue.write_buffer(&res.fallen, 0, bytemuck::cast_slice(&fallen));
    ctx.queue.write_buffer(&res.stamps, 0, bytemuck::cast_slice(&stamps));
    let display = DisplayPass::new(&ctx.device, &res);
    let mut timer = GpuTimer::disabled();
    for mode in [0, 1, 2] {
        let rp = DisplayParams {
            origin: [0, 0],
            resolution: RES as u32,
            depth_m: 0.0,
            elevation: 1.5,
            mode,
            low_m,
            high_m,
            use_fallen: 1,
            texel_m: params.texel_m(),
            blur: 0,
            // All of it snowfall (none a berm).
            open_fallen_m: f32::MAX,
            ..DisplayParams::default()
        };
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("rim at zero depth") });
        display.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), &res, &rp);
        ctx.queue.submit([encoder.finish()]);
        // The displayed height is the upper (f16) half of each word, above the terrain.
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &res.snow).expect("readback"));
        let gpu: Vec<f32> = words.iter().zip(&terrain).map(|(&w, &t)| snow_word::shown(w, t)).collect();
        let cpu = cpu::display::shown(&rp, &terrain, &snow_words, &stamps, &fallen);
        assert!(gpu.iter().all(|h| h.is_finite()), "mode {mode}: NaN in the displayed surface; seed {seed}");
        // Within an f16 step of the height above the terrain (f16 in the word).
        let worst = gpu.iter().zip(&cpu).zip(&terrain).map(|((g, c), t)| (g - c).abs() / ((c - t).abs() * 2f32.powi(-10) + 1e-4)).fold(0.0f32, f32::max);
        assert!(worst <= 1.0, "mode {mode}: GPU and CPU differ by {worst} of the tolerance; seed {seed}");
        // Bare texels show their snow (origin 0: window-local is toroidal), with no rim.
        let bare: Vec<usize> = (0..n).filter(|&s| fallen[s] == 0.0).collect();
        assert!(bare.len() > n / 3);
        assert!(bare.iter().all(|&s| gpu[s] == terrain[s] && snow[s] == terrain[s]), "mode {mode}: a bare texel is not shown as its snow; seed {seed}");
        // And the snowy ones still get their remap or rims.
        let changed = (0..n).filter(|&s| fallen[s] > 0.0 && (gpu[s] - snow[s]).abs() > 1e-4).count();
        assert!(changed > n / 20, "mode {mode}: only {changed} snowy texels remapped; seed {seed}");
    }
}

/// Mean linear-ish brightness (sum of RGB / 765) of the pixels in columns
/// `cols` and rows `rows` of an RGBA8 image `width` wide.
fn mean_brightness(rgba: &[u8], width: u32, cols: std::ops::Range<u32>, rows: std::ops::Range<u32>) -> f64 {
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in rows {
        for x in cols.clone() {
            let k = ((y * width + x) * 4) as usize;
            sum += f64::from(rgba[k]) + f64::from(rgba[k + 1]) + f64::from(rgba[k + 2]);
            n += 1.0;
        }
    }
    sum / n / 765.0
}

#[test]
fn snowfall_on_bare_ground_shows_no_square_at_the_window_edge() {
    use snowpack::{Camera, EnvironmentMap, RenderParams, Renderer};
    let Some(ctx) = testing::gpu() else { return };
    // Bare ground, then 0.2 m of snow falls; the window is 16 m wide around
    // the origin and the camera looks straight down on its edge at x = 8 m.
    let fall = Snowfall { rate_m_per_s: 0.2, max_m: 1.0, ..Snowfall::default() };
    let params = SnowParams { extent_m: 16.0, resolution: 256, depth_m: 0.0, snowfall: Some(fall), ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: GROUND_M }, DVec2::ZERO).expect("window");
    for _ in 0..60 {
        snow.step(ctx, &[], DT).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    assert!((snow.fallen_m() - 0.2).abs() < 1e-3, "fallen {}", snow.fallen_m());
    let edge = snow.origin_m().expect("placed").x as f32 + 16.0;
    let sky = EnvironmentMap::from_hdr(include_bytes!("../../../assets/spiaggia_di_mondello_1k.hdr")).expect("sky");
    let mut renderer =
        Renderer::new(ctx, &snow, &sky, RenderParams { shadow_map_size: 512, ..RenderParams::default() }, snowpack::IMAGE_FORMAT).expect("renderer");
    let camera = Camera { position: Vec3::new(edge, GROUND_M + 6.0, -0.01), target: Vec3::new(edge, GROUND_M, 0.0), fov_deg: 50.0 };
    let (w, h) = (256_u32, 160_u32);
    let rgba = renderer.render_image(ctx, &snow, &[], &camera, (w, h)).expect("frame");
    if let Ok(dir) = std::env::var("SNOWPACK_TEST_IMAGES") {
        let path = std::path::Path::new(&dir).join("bare_ground_snowfall_edge.png");
        image::save_buffer(&path, &rgba, w, h, image::ExtendedColorType::Rgba8).expect("png");
    }
    // The image's halves are the two sides of the edge (which is which
    // depends on the view's handedness); away from the centre column the
    // snow inside and outside the window must look the same.
    let rows = h / 2 - 30..h / 2 + 30;
    let left = mean_brightness(&rgba, w, w / 2 - 60..w / 2 - 8, rows.clone());
    let right = mean_brightness(&rgba, w, w / 2 + 8..w / 2 + 60, rows.clone());
    // And the band across the edge matches both (no line along it).
    let seam = mean_brightness(&rgba, w, w / 2 - 3..w / 2 + 3, rows);
    println!("brightness: one side {left:.4}, the other {right:.4}, across the edge {seam:.4}");
    assert!(left > 0.5 && right > 0.5, "not snow-white: {left}, {right}");
    assert!((left - right).abs() / left.max(right) < 0.03, "the window's edge shows: {left} against {right}");
    assert!((seam - 0.5 * (left + right)).abs() / left.max(right) < 0.03, "a line along the edge: {seam}");
    // Point samples agree too: the rest height the renderer and the
    // sampling module use outside is what the window holds inside.
    let inside = snow.read_snow(ctx).expect("snow");
    let rest_inside = inside[128 * 256 + 255];
    let outside = snowpack::SnowWindowUniform::new(&snow);
    assert!((GROUND_M + outside.rest_depth_m() - rest_inside).abs() < 1e-3, "rest outside {} against {rest_inside} inside", GROUND_M + outside.rest_depth_m());
}
