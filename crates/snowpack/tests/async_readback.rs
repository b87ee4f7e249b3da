//! The non-blocking paths the browser build uses (where `device.poll` cannot
//! wait), run natively: async readbacks of buffers, textures and the snow
//! equal the blocking ones, and point answers arrive with no blocking call at
//! all, as a browser's frame loop gets them.

use glam::{DVec2, Vec2, Vec3};
use snowpack::low_level::SnowInspect;
use snowpack::low_level::gpu::readback::{TextureReadback, read_buffer, read_buffer_async};
use snowpack::{Deformer, NoiseTerrain, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
use snowpack_testkit::testing::{self, Rng};

#[test]
fn async_buffer_and_texture_readbacks_equal_the_blocking_ones() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("async_buffer_and_texture_readbacks_equal_the_blocking_ones");
    let mut rng = Rng::new(seed);
    let words: Vec<u32> = (0..4099).map(|_| rng.next_u64() as u32).collect();
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("random words"),
        size: (words.len() * 4) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue.write_buffer(&buffer, 0, bytemuck::cast_slice(&words));
    let blocking = read_buffer(ctx, &buffer).expect("blocking read");
    let async_bytes = pollster::block_on(read_buffer_async(ctx, &buffer)).expect("async read");
    assert_eq!(async_bytes, blocking, "seed {seed}");
    assert_eq!(bytemuck::pod_collect_to_vec::<u8, u32>(&async_bytes), words, "seed {seed}");

    // A texture whose rows need padding (width 37: 148 bytes, aligned to 256).
    let (w, h) = (37, 23);
    let texels: Vec<u8> = (0..w * h * 4).map(|_| rng.next_u64() as u8).collect();
    let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("random texels"),
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    ctx.queue.write_texture(
        texture.as_image_copy(),
        &texels,
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w * 4), rows_per_image: None },
        wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
    );
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("two copies") });
    let first = TextureReadback::record(&ctx.device, &mut encoder, &texture);
    let second = TextureReadback::record(&ctx.device, &mut encoder, &texture);
    ctx.queue.submit([encoder.finish()]);
    let from_async = pollster::block_on(second.read_async(ctx)).expect("async texture read");
    assert_eq!(from_async, texels, "seed {seed}");
    assert_eq!(first.read(ctx).expect("blocking texture read"), texels, "seed {seed}");
}

#[test]
fn snow_reads_and_point_answers_need_no_blocking_call() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("snow_reads_and_point_answers_need_no_blocking_call");
    let mut rng = Rng::new(seed);
    let params = SnowParams { extent_m: 16.0, resolution: 128, depth_m: rng.range(0.2, 0.6), ..SnowParams::default() };
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: rng.next_u64() as u32, amplitude_m: 1.0, wavelength_m: 8.0, base_m: 0.0 });
    // Off the origin, so the toroidal window's layout matters.
    let center = DVec2::new(f64::from(rng.range(-50.0, 50.0)), f64::from(rng.range(-50.0, 50.0)));
    let mut snow = SnowDeformation::new(ctx, params.clone(), terrain.clone(), center).expect("window");
    let (cx, cz) = (center.x as f32, center.y as f32);
    let spheres: Vec<Deformer> = (0..8)
        .map(|_| {
            let (x, z) = (cx + rng.range(-6.0, 5.0), cz + rng.range(-6.0, 5.0));
            Deformer::Sphere { center: Vec3::new(x, terrain.height_at(x, z) + rng.range(0.1, 0.4), z), radius: rng.range(0.3, 0.7) }
        })
        .collect();
    // Each sphere's centre is pressed; a far point is untouched.
    let mut points: Vec<Vec2> =
        spheres.iter().map(|d| if let Deformer::Sphere { center, .. } = d { Vec2::new(center.x, center.z) } else { Vec2::ZERO }).collect();
    points.push(Vec2::new(cx + 7.0, cz + 7.0));

    // The browser's loop: ask and encode, submit and go on (each encode
    // takes what came back after a non-blocking poll); never `finish` or a
    // blocking read.
    let mut answered = None;
    for frame in 0..600 {
        let ticket = snow.step_frame(ctx, &SnowFrame::new(1.0 / 60.0, &spheres).with_queries(&points)).expect("frame");
        if let Some(a) = snow.point_answers()
            && frame >= 4
        {
            answered = Some((a.clone(), ticket));
            break;
        }
    }
    let (answers, _) = answered.unwrap_or_else(|| panic!("no point answer came back within 600 frames (seed {seed})"));
    assert_eq!(answers.points, points, "seed {seed}");
    // The spheres stand still after the first frame, so any answer since then
    // is the settled snow the async read sees.
    let words = pollster::block_on(snow.read_snow_words_async(ctx)).expect("async snow read");
    assert_eq!(words, snow.read_snow_words(ctx).expect("blocking snow read"), "seed {seed}");
    let heights = snow.read_snow(ctx).expect("heights");
    let corner = snow.origin_m().expect("placed");
    let texel = params.texel_m();
    let r = params.resolution as usize;
    for (k, (p, sample)) in points.iter().zip(&answers.samples).enumerate() {
        let sample = sample.unwrap_or_else(|| panic!("point {k} {p:?} is inside the window (seed {seed})"));
        let j = (((f64::from(p.x) - corner.x) / f64::from(texel)).floor() as usize).min(r - 1);
        let i = (((f64::from(p.y) - corner.y) / f64::from(texel)).floor() as usize).min(r - 1);
        // A point between texel centres is interpolated: within a few
        // millimetres of its texel where the snow is smooth, within the
        // neighbourhood's range everywhere.
        let around: Vec<f32> = (i.saturating_sub(1)..=(i + 1).min(r - 1))
            .flat_map(|a| (j.saturating_sub(1)..=(j + 1).min(r - 1)).map(move |b| (a, b)))
            .map(|(a, b)| heights[a * r + b])
            .collect();
        let (lo, hi) = around.iter().fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
        assert!(
            sample.height_m >= lo - 1e-3 && sample.height_m <= hi + 1e-3,
            "point {k} {p:?}: answered {} outside the texels around it {lo}..{hi} (seed {seed})",
            sample.height_m
        );
    }
    let rest = |p: Vec2| terrain.height_at(p.x, p.y) + params.depth_m;
    for (k, p) in points[..spheres.len()].iter().enumerate() {
        let s = answers.samples[k].expect("inside");
        assert!(s.height_m < rest(*p) - 0.05, "sphere {k} pressed its centre: {} vs rest {} (seed {seed})", s.height_m, rest(*p));
    }
    let far = answers.samples[spheres.len()].expect("inside");
    let far_p = points[spheres.len()];
    let near_sphere = spheres.iter().any(|d| matches!(d, Deformer::Sphere { center, .. } if Vec2::new(center.x, center.z).distance(far_p) < 1.0));
    if !near_sphere {
        assert!((far.height_m - rest(far_p)).abs() < 0.02, "the far point is untouched: {} vs {} (seed {seed})", far.height_m, rest(far_p));
    }
}
