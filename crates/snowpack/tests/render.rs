//! The renderer: its compute passes against their CPU twins, and frames
//! checked for cracks between levels of detail and for geomorph continuity.

use glam::{DVec2, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::low_level::frame::FrameContext;
use snowpack::low_level::gpu::GpuTimer;
use snowpack::low_level::gpu::read_buffer;
use snowpack::low_level::render::ao::{AoParams, AoPass};
use snowpack::low_level::render::environment::{self, EnvironmentPass};
use snowpack::{Camera, Deformer, EnvironmentMap, NoiseTerrain, RenderParams, Renderer, SnowDeformation, SnowParams, TerrainSource};
use snowpack::{DebugView, IMAGE_FORMAT};
use snowpack_testkit::cpu;
use snowpack_testkit::testing::{self, Rng};

#[test]
fn ao_matches_cpu_twin() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("ao twin");
    let mut rng = Rng::new(seed);
    let res = 48u32;
    let texel = 0.0625;
    // Bumpy heights with a few deep pits and ridges, as trails and rims make.
    let heights: Vec<f32> = (0..res * res).map(|_| rng.range(0.0, 0.05) + if rng.range(0.0, 1.0) > 0.9 { rng.range(-0.5, 0.5) } else { 0.0 }).collect();
    let packed: Vec<[u32; 2]> = heights.iter().map(|h| [h.to_bits(), 0]).collect();
    let surface = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test surface"),
        size: u64::from(res * res) * 8,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue.write_buffer(&surface, 0, bytemuck::cast_slice(&packed));
    let pass = AoPass::new(&ctx.device, &surface, res);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    let params = AoParams { resolution: res, steps: AoPass::STEPS, texel_m: texel, strength: 0.9 };
    pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer), params);
    ctx.queue.submit([encoder.finish()]);
    let gpu: Vec<f32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &pass.ao).expect("read ao"));
    let cpu = cpu::ao::ambient_occlusion(&heights, res, AoPass::STEPS, texel, 0.9);
    let worst = gpu.iter().zip(&cpu).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "seed {seed}: AO differs by {worst}");
    assert!(cpu.iter().any(|&a| a < 0.8), "seed {seed}: nothing occluded, the test proves little");
}

#[test]
fn environment_passes_match_cpu_twin() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("environment twin");
    let mut rng = Rng::new(seed);
    let (w, h) = (128u32, 64u32);
    let texels: Vec<[f32; 4]> = (0..w * h)
        .map(|_| {
            let hot = if rng.range(0.0, 1.0) > 0.995 { 200.0 } else { 1.0 };
            [rng.range(0.0, 2.0) * hot, rng.range(0.0, 2.0) * hot, rng.range(0.0, 2.0) * hot, 1.0]
        })
        .collect();
    let env = EnvironmentMap { width: w, height: h, texels };
    let pass = EnvironmentPass::new(&ctx.device, &ctx.queue, &env);
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    pass.record(&mut FrameContext::new(ctx, &mut encoder, &mut timer));
    ctx.queue.submit([encoder.finish()]);
    let small: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &pass.downsampled).expect("read"));
    let pre: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &pass.prefiltered).expect("read"));
    let cpu_small = cpu::env_downsample::downsample(&env.texels, w, h, environment::DOWNSAMPLED_W, environment::DOWNSAMPLED_H, environment::CLAMP_LUMINANCE);
    let cpu_pre = cpu::env_prefilter::prefilter(
        &cpu_small,
        environment::DOWNSAMPLED_W,
        environment::DOWNSAMPLED_H,
        environment::PREFILTERED_W,
        environment::PREFILTERED_H,
        environment::PREFILTERED_LEVELS,
    );
    let rel = |a: &[[f32; 4]], b: &[[f32; 4]]| {
        a.iter().zip(b).flat_map(|(p, q)| (0..3).map(move |k| (p[k] - q[k]).abs() / q[k].abs().max(1e-3))).fold(0.0f32, f32::max)
    };
    let d = rel(&small, &cpu_small);
    assert!(d < 1e-5, "seed {seed}: downsample differs by {d} (relative)");
    // The prefilter sums 2048 terms with GPU transcendentals: relative 1e-3.
    let d = rel(&pre, &cpu_pre);
    assert!(d < 1e-3, "seed {seed}: prefilter differs by {d} (relative)");
    // Irradiance of a uniform hemisphere of radiance L is L: sanity of the weights.
    let mean: f32 = cpu_small.iter().map(|t| t[0]).sum::<f32>() / cpu_small.len() as f32;
    let irr: f32 = cpu_pre[..512].iter().map(|t| t[0]).sum::<f32>() / 512.0;
    assert!((irr - mean).abs() < 0.15 * mean, "seed {seed}: mean irradiance/pi {irr} vs mean radiance {mean}");
}

/// A deformed window over hilly terrain, with a sphere's trail in it.
fn hilly_snow(ctx: &snowpack::GpuContext) -> (SnowDeformation, Vec<Deformer>) {
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: 5, base_m: 0.0, amplitude_m: 3.0, wavelength_m: 14.0 });
    let params = SnowParams { extent_m: 16.0, resolution: 256, depth_m: 0.5, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, terrain.clone(), DVec2::ZERO).expect("window");
    let mut actors = Vec::new();
    for k in 0..12 {
        let x = -6.0 + k as f32;
        let center = Vec3::new(x, terrain.height_at(x, 1.0) + 0.45, 1.0);
        actors = vec![Deformer::Sphere { center, radius: 0.6 }];
        snow.step(ctx, &actors, 1.0 / 30.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    (snow, actors)
}

/// What a frame shows: the fraction of pixels that are not `background`
/// (magenta), the number of distinct colours (5 bits a channel) among them,
/// and the standard deviation of their luminance.
fn frame_content(image: &[u8], background: bool) -> (f64, usize, f64) {
    let pixels: Vec<&[u8]> = image.chunks_exact(4).filter(|p| !(background && p[0] > 200 && p[1] < 40 && p[2] > 200)).collect();
    let colours: std::collections::HashSet<[u8; 3]> = pixels.iter().map(|p| [p[0] >> 3, p[1] >> 3, p[2] >> 3]).collect();
    let lum: Vec<f64> = pixels.iter().map(|p| p[..3].iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0).collect();
    let n = lum.len().max(1) as f64;
    let mean = lum.iter().sum::<f64>() / n;
    let spread = (lum.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / n).sqrt();
    (pixels.len() as f64 / (image.len() / 4) as f64, colours.len(), spread)
}

/// Fails on a blank, uniform or mostly empty frame: snow over hills, shaded
/// by its normals, covers most of the view in many colours.
fn assert_shows_snow(image: &[u8], background: bool, what: &str) {
    let (covered, colours, spread) = frame_content(image, background);
    eprintln!("{what}: {:.0}% of the frame drawn, {colours} colours, luminance spread {spread:.1}/255", covered * 100.0);
    assert!(
        covered > 0.5 && colours > 50 && spread > 5.0,
        "{what}: the frame is blank or nearly ({:.0}% drawn, {colours} colours, spread {spread:.1})",
        covered * 100.0
    );
}

fn renderer(ctx: &snowpack::GpuContext, snow: &SnowDeformation, params: RenderParams) -> Renderer {
    let env = EnvironmentMap::procedural(Vec3::new(0.5, 0.6, 0.4).normalize());
    Renderer::new(ctx, snow, &env, RenderParams { shadow_map_size: 1024, ..params }, IMAGE_FORMAT).expect("renderer")
}

#[test]
fn no_cracks_between_levels_seen_from_above() {
    let Some(ctx) = testing::gpu() else { return };
    let (snow, actors) = hilly_snow(ctx);
    let params = RenderParams { background: Some(Vec3::new(1.0, 0.0, 1.0)), debug_view: DebugView::Normals, ..RenderParams::default() };
    let mut r = renderer(ctx, &snow, params);
    let size = (256, 256);
    // Straight down from 10 m over the hills with a wide lens: levels 0 to 3 meet in view,
    // and the window's edge (where the detail bonus fades) crosses it.
    for eye in [Vec3::new(0.0, 14.0, 0.0), Vec3::new(9.0, 12.0, -7.0)] {
        let camera = Camera { position: eye, target: eye - Vec3::Y, fov_deg: 100.0 };
        let image = r.render_image(ctx, &snow, &actors, &camera, size).expect("frame");
        assert_shows_snow(&image, true, &format!("from {eye}"));
        let stats = r.stats();
        assert!(stats.levels.1 > stats.levels.0, "only level {:?} in view: no seams to check", stats.levels);
        // Normals never show magenta (x and z would have to be 1 and y -1); the background does.
        let holes = image.chunks_exact(4).filter(|p| p[0] > 200 && p[1] < 40 && p[2] > 200).count();
        assert_eq!(holes, 0, "{holes} background pixels show through the snow from {eye}");
    }
}

#[test]
fn small_camera_steps_change_the_frame_little() {
    let Some(ctx) = testing::gpu() else { return };
    let (snow, actors) = hilly_snow(ctx);
    let mut r = renderer(ctx, &snow, RenderParams { debug_view: DebugView::Normals, ..RenderParams::default() });
    let size = (240, 160);
    let at = |dz: f32| Camera { position: Vec3::new(0.0, 6.0, -14.0 + dz), target: Vec3::new(0.0, 0.0, 4.0 + dz), fov_deg: 60.0 };
    let base = r.render_image(ctx, &snow, &actors, &at(0.0), size).expect("frame");
    assert_shows_snow(&base, false, "the first frame");
    // Sweep 2 cm steps across a metre, so vertices cross morph ranges on the way.
    let mut worst = 0.0f64;
    let mut previous = base.clone();
    for k in 1..=50 {
        let image = r.render_image(ctx, &snow, &actors, &at(k as f32 * 0.02), size).expect("frame");
        worst = worst.max(testing::mean_abs_difference(&previous, &image));
        previous = image;
    }
    // A 2 cm step moves the hills a fraction of a pixel; a popping level or a
    // crack would change whole patches at once.
    assert!(worst < 2.0, "a 2 cm camera step changed the frame by {worst:.2}/255 on average");
    // ...while the metre of steps does move the view: frames that do not
    // follow the camera (or show nothing) would pass the bound above.
    let moved = testing::mean_abs_difference(&base, &previous);
    eprintln!("2 cm steps: at most {worst:.2}/255; the whole metre: {moved:.2}/255");
    assert!(moved > 2.0 * worst.max(0.25), "a metre of camera steps changed the frame by only {moved:.2}/255 (steps: {worst:.2})");
}

/// Mean of the 8-bit RGB channels of pixel `k`.
fn luminance(image: &[u8], k: usize) -> f64 {
    image[4 * k..4 * k + 3].iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0
}

#[test]
fn compacted_snow_is_darker_only_where_pressed() {
    let Some(ctx) = testing::gpu() else { return };
    // A sphere dragged along z = 0 over flat ground with its bottom 15 cm
    // above it (70 % of the half metre pressed at the centre line), and one
    // along z = 2 with its bottom 4 cm above it (92 %: the ground shows
    // through), no bare ground.
    let params = SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.5, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let mut actors = Vec::new();
    for k in 0..40 {
        let x = -3.0 + 0.15 * k as f32;
        actors = vec![Deformer::Sphere { center: Vec3::new(x, 0.75, 0.0), radius: 0.6 }, Deformer::Sphere { center: Vec3::new(x, 0.64, 2.0), radius: 0.6 }];
        snow.step(ctx, &actors, 1.0 / 30.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    actors.clear();
    let camera = Camera { position: Vec3::new(0.0, 5.0, -2.5), target: Vec3::new(0.0, 0.0, 0.5), fov_deg: 60.0 };
    let size = (160, 120);
    let on = RenderParams { ao_strength: 0.0, ..RenderParams::default() };
    let off = RenderParams { material: on.material.without_compaction(), ..on };
    let mut r = renderer(ctx, &snow, on);
    let lit_on = r.render_image(ctx, &snow, &actors, &camera, size).expect("frame");
    r.set_params(off);
    let lit_off = r.render_image(ctx, &snow, &actors, &camera, size).expect("frame");
    let mut no_ground = on;
    no_ground.material.ground_show_through = 0.0;
    r.set_params(no_ground);
    let lit_no_ground = r.render_image(ctx, &snow, &actors, &camera, size).expect("frame");
    r.set_params(RenderParams { debug_view: DebugView::Deformation, ..on });
    let pressed = r.render_image(ctx, &snow, &actors, &camera, size).expect("frame");

    // The deformation view is grey (0.12) plus red for the fraction pressed.
    let (mut deep, mut untouched) = (Vec::new(), Vec::new());
    for k in 0..(size.0 * size.1) as usize {
        let (red, green) = (i32::from(pressed[4 * k]), i32::from(pressed[4 * k + 1]));
        if red - green > 90 {
            deep.push(k);
        } else if (red - green).abs() <= 1 {
            untouched.push(k);
        }
    }
    assert!(deep.len() > 300 && untouched.len() > 3000, "{} pressed and {} untouched pixels in view", deep.len(), untouched.len());
    let mean = |image: &[u8], ks: &[usize]| ks.iter().map(|&k| luminance(image, k)).sum::<f64>() / ks.len() as f64;
    let (deep_on, deep_off) = (mean(&lit_on, &deep), mean(&lit_off, &deep));
    let (fresh_on, fresh_off) = (mean(&lit_on, &untouched), mean(&lit_off, &untouched));
    eprintln!("{} pressed pixels: {deep_on:.1} on, {deep_off:.1} off; {} untouched: {fresh_on:.2} on, {fresh_off:.2} off", deep.len(), untouched.len());
    // The packed albedo (0.6..0.76 against 0.92..0.98) darkens the trail floor clearly...
    assert!(deep_on < deep_off - 15.0, "trail floor {deep_on:.1}/255 with compaction, {deep_off:.1}/255 without");
    // ...and leaves untouched snow as it was (sparkle and detail are unchanged there).
    assert!((fresh_on - fresh_off).abs() < 0.5, "untouched snow {fresh_on:.1}/255 with compaction, {fresh_off:.1}/255 without");
    // The ground (brown, dark) shows only in the deeper print: pixels it
    // changes are pressed ones, and they turn darker and (a little: the blue
    // sky and scattering light the trench floor) warmer.
    // Warmth: red over blue (the packed snow is blue-grey, the ground brown).
    let warmth = |image: &[u8], k: usize| f64::from(image[4 * k]) / f64::from(image[4 * k + 2]).max(1.0);
    let through: Vec<usize> = (0..(size.0 * size.1) as usize).filter(|&k| (luminance(&lit_on, k) - luminance(&lit_no_ground, k)).abs() > 4.0).collect();
    assert!(through.len() > 100, "the ground shows through in only {} pixels", through.len());
    assert!(through.iter().all(|k| deep.contains(k)), "the ground shows through outside the pressed trails");
    let n = through.len() as f64;
    let darker = through.iter().map(|&k| luminance(&lit_no_ground, k) - luminance(&lit_on, k)).sum::<f64>() / n;
    let warmer = through.iter().map(|&k| warmth(&lit_on, k) - warmth(&lit_no_ground, k)).sum::<f64>() / n;
    eprintln!("ground shows through in {} pixels: {darker:.1}/255 darker, red/blue up {warmer:.3}", through.len());
    assert!(darker > 8.0 && warmer > 0.0, "where the ground shows through: {darker:.1}/255 darker, red/blue up {warmer:.3}");
}

/// The compacted look follows the snow's packing, not its shape
/// (docs/rendering.md): two trails pressed alike, 35 cm into half a metre,
/// the first 5 s before the second, with 2 cm/s of refill. The first has
/// 10 cm of fresh snow over its packed floor and looks fresh; the second,
/// barely refilled, looks packed; both are still well below rest, which is
/// all the look followed before.
#[test]
fn a_refilled_trail_looks_fresh_and_a_new_one_packed() {
    let Some(ctx) = testing::gpu() else { return };
    let params = SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.5, refill_m_per_s: 0.02, ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    let press = |snow: &mut SnowDeformation, z: f32| {
        for k in 0..40 {
            let x = -3.0 + 0.15 * k as f32;
            snow.step(ctx, &[Deformer::Sphere { center: Vec3::new(x, 0.75, z), radius: 0.6 }], 1.0 / 30.0).expect("frame");
        }
    };
    press(&mut snow, 2.0);
    for _ in 0..150 {
        snow.step(ctx, &[], 1.0 / 30.0).expect("frame");
    }
    press(&mut snow, 0.0);
    snow.step(ctx, &[], 1.0 / 30.0).expect("frame");
    snow.finish(ctx).expect("finish");
    let camera = Camera { position: Vec3::new(0.0, 5.0, -2.5), target: Vec3::new(0.0, 0.0, 0.5), fov_deg: 60.0 };
    let size = (160, 120);
    let on = RenderParams { ao_strength: 0.0, ..RenderParams::default() };
    let mut r = renderer(ctx, &snow, on);
    let lit = r.render_image(ctx, &snow, &[], &camera, size).expect("frame");
    r.set_params(RenderParams { material: on.material.without_compaction(), ..on });
    let fresh = r.render_image(ctx, &snow, &[], &camera, size).expect("frame");
    r.set_params(RenderParams { debug_view: DebugView::Deformation, ..on });
    let pressed = r.render_image(ctx, &snow, &[], &camera, size).expect("frame");
    // Pixels well below rest (the deformation view's red), split by the
    // image row: the far trail (z = 2, refilled) is higher in the image.
    let deep: Vec<usize> = (0..(size.0 * size.1) as usize).filter(|&k| i32::from(pressed[4 * k]) - i32::from(pressed[4 * k + 1]) > 60).collect();
    let row = |k: usize| k / size.0 as usize;
    let split = (deep.iter().map(|&k| row(k)).min().unwrap_or(0) + deep.iter().map(|&k| row(k)).max().unwrap_or(0)) / 2;
    let (far, near): (Vec<usize>, Vec<usize>) = deep.iter().partition(|&&k| row(k) < split);
    assert!(far.len() > 100 && near.len() > 100, "{} far and {} near pixels below rest", far.len(), near.len());
    // How much darker the compacted look makes each trail than fresh snow would be.
    let darkened = |ks: &[usize]| ks.iter().map(|&k| luminance(&fresh, k) - luminance(&lit, k)).sum::<f64>() / ks.len() as f64;
    let (refilled, new) = (darkened(&far), darkened(&near));
    eprintln!("compacted look: the refilled trail {refilled:.1}/255 darker than fresh, the new one {new:.1}/255");
    assert!(new > 10.0 && refilled < 0.25 * new, "refilled trail {refilled:.1}/255 darker than fresh snow, new trail {new:.1}/255");
}
