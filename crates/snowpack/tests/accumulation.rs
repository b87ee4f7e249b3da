//! Accumulation physics on the GPU: snow settles where the sky reaches, on
//! objects and on the ground, follows slope stability, and stays on objects
//! that move. Each test runs the whole deformation frame with snowfall.

use glam::{DVec2, Quat, Vec3};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::SnowParamsExt;
use snowpack::{GpuContext, SnowDeformation, SnowParams, TerrainSource};
use snowpack::{ObjectShape, SnowObject, Snowfall};
use snowpack_testkit::testing;

const EXTENT_M: f32 = 16.0;
const RESOLUTION: u32 = 128;
const DEPTH_M: f32 = 0.3;
const RATE: f32 = 0.01;
const DT: f32 = 0.05;

fn snowfall(direction: Vec3) -> Snowfall {
    Snowfall { direction: direction.normalize(), rate_m_per_s: RATE, flutter_deg: 0.0, noise: 0.0, atlas_resolution: 256, ..Snowfall::default() }
}

fn object(name: &str, shape: ObjectShape, position: Vec3, rotation: Quat) -> SnowObject {
    SnowObject { name: name.into(), shape, position, rotation, dilate: true }
}

fn slab(size: Vec3) -> ObjectShape {
    ObjectShape::Box { size_m: size }
}

fn window(ctx: &GpuContext, fall: Snowfall, objects: &[SnowObject]) -> SnowDeformation {
    let params = SnowParams { extent_m: EXTENT_M, resolution: RESOLUTION, depth_m: DEPTH_M, blur: false, snowfall: Some(fall), ..SnowParams::default() };
    let mut snow = SnowDeformation::new(ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO).expect("window");
    snow.set_objects(ctx, objects).expect("objects");
    snow
}

fn run(ctx: &GpuContext, snow: &mut SnowDeformation, frames: u32) {
    for _ in 0..frames {
        snow.step(ctx, &[], DT).expect("frame");
    }
    snow.finish(ctx).expect("finish");
}

/// Snow depth above the terrain at world (x, z), from a window-local read-back.
fn depth_at(snow: &SnowDeformation, heights: &[f32], x: f32, z: f32) -> f32 {
    let origin = snow.origin_m().expect("placed");
    let texel = f64::from(EXTENT_M / RESOLUTION as f32);
    let j = ((f64::from(x) - origin.x) / texel).floor() as usize;
    let i = ((f64::from(z) - origin.y) / texel).floor() as usize;
    heights[i * RESOLUTION as usize + j]
}

#[test]
fn straight_down_snow_reaches_open_ground_and_a_table_top_but_not_under_it() {
    let Some(ctx) = testing::gpu() else { return };
    let table = object("table", slab(Vec3::new(2.0, 0.1, 1.0)), Vec3::new(0.0, 1.0, 0.0), Quat::IDENTITY);
    let mut snow = window(ctx, snowfall(Vec3::NEG_Y), &[table]);
    let frames = 100;
    run(ctx, &mut snow, frames);
    let fallen = RATE * DT * frames as f32;
    assert!((snow.fallen_m() - fallen).abs() < 1e-4);
    let h = snow.read_snow(ctx).expect("snow");
    for (x, z) in [(5.0, 5.0), (-4.0, 2.0), (3.0, -6.0)] {
        let d = depth_at(&snow, &h, x, z);
        assert!((d - (DEPTH_M + fallen)).abs() < 1e-4, "open ground at ({x}, {z}): {d} m, want {}", DEPTH_M + fallen);
    }
    for (x, z) in [(0.0, 0.0), (-0.7, 0.3), (0.7, -0.3)] {
        let d = depth_at(&snow, &h, x, z);
        assert!((d - DEPTH_M).abs() < 1e-4, "under the table at ({x}, {z}): {d} m, want {DEPTH_M} (no snowfall)");
    }
    let acc = snow.accumulation().expect("objects");
    let stats = acc.stats(&acc.read_atlas(ctx).expect("atlas"));
    let top = stats[0];
    assert!((top.mean_m - fallen).abs() < 0.1 * fallen, "table top holds {} m on average, want {fallen} m", top.mean_m);
    assert!(top.covered_fraction > 0.95, "table top covered {}", top.covered_fraction);
}

#[test]
fn a_roof_beyond_the_angle_of_repose_sheds_its_snow_and_a_gentle_one_keeps_it() {
    let Some(ctx) = testing::gpu() else { return };
    let fall = snowfall(Vec3::NEG_Y);
    assert!(fall.repose_deg > 15.0 && fall.repose_deg < 50.0);
    let roof = |name: &str, x: f32, deg: f32| object(name, slab(Vec3::new(2.0, 0.05, 2.0)), Vec3::new(x, 2.0, 0.0), Quat::from_rotation_z(deg.to_radians()));
    let mut snow = window(ctx, fall, &[roof("steep", -3.0, 50.0), roof("gentle", 3.0, 15.0)]);
    let frames = 100;
    run(ctx, &mut snow, frames);
    let acc = snow.accumulation().expect("objects");
    let atlas = acc.read_atlas(ctx).expect("atlas");
    let bake = acc.bake();
    // The roof itself: each slab's top face (object normal +y); its thin edges are other surfaces.
    let roof_texels =
        |object: u32| -> Vec<f32> { (0..atlas.len()).filter(|&k| bake.owner[k] == object && bake.normal_area[k][1] > 0.99).map(|k| atlas[k]).collect() };
    let fallen = RATE * DT * frames as f32;
    let steep = roof_texels(0);
    assert!(steep.iter().all(|&a| a == 0.0), "the 50° roof holds up to {} m", steep.iter().fold(0.0f32, |m, &a| m.max(a)));
    // A surface tilted by t catches cos(t) of the snow per unit area.
    let want = fallen * 15f32.to_radians().cos();
    let gentle = roof_texels(1);
    let mean = gentle.iter().sum::<f32>() / gentle.len() as f32;
    assert!((mean - want).abs() < 0.1 * want, "the 15° roof holds {mean} m, want about {want} m");
    let covered = gentle.iter().filter(|&&a| a > 1e-3).count() as f32 / gentle.len() as f32;
    assert!(covered > 0.95, "the 15° roof is covered {covered}");
    let stats = acc.stats(&atlas);
    assert!(stats[1].mean_m > 10.0 * stats[0].mean_m, "upward surfaces: gentle {:?}, steep {:?}", stats[1], stats[0]);
}

#[test]
fn wind_from_the_side_leaves_the_lee_of_a_box_bare() {
    let Some(ctx) = testing::gpu() else { return };
    // Flakes travel +x at 45°: the box's shadow on the snow reaches (1.0 - 0.3) m past its lee face.
    let cube = object("crate", slab(Vec3::ONE), Vec3::new(0.0, 0.5, 0.0), Quat::IDENTITY);
    let mut snow = window(ctx, snowfall(Vec3::new(1.0, -1.0, 0.0)), &[cube]);
    let frames = 100;
    run(ctx, &mut snow, frames);
    let fallen = RATE * DT * frames as f32;
    let h = snow.read_snow(ctx).expect("snow");
    for x in [0.65, 0.8, 1.0] {
        let d = depth_at(&snow, &h, x, 0.0);
        assert!((d - DEPTH_M).abs() < 1e-4, "lee side at x = {x}: {d} m, want {DEPTH_M} (sheltered)");
    }
    for (x, z) in [(-0.8, 0.0), (-2.0, 0.0), (2.0, 0.0), (0.8, 1.5)] {
        let d = depth_at(&snow, &h, x, z);
        assert!((d - (DEPTH_M + fallen)).abs() < 1e-4, "open ground at ({x}, {z}): {d} m");
    }
    let acc = snow.accumulation().expect("objects");
    let stats = acc.stats(&acc.read_atlas(ctx).expect("atlas"));
    assert!((stats[0].mean_m - fallen).abs() < 0.1 * fallen, "the crate's top holds {} m, want {fallen} m", stats[0].mean_m);
}

#[test]
fn an_object_moved_after_snowing_keeps_its_snow_and_one_turned_over_sheds_it() {
    let Some(ctx) = testing::gpu() else { return };
    let bench = object("bench", slab(Vec3::new(2.0, 0.2, 0.6)), Vec3::new(-2.0, 1.0, 0.0), Quat::IDENTITY);
    let ball = object("ball", ObjectShape::Sphere { radius_m: 0.6 }, Vec3::new(2.0, 1.5, 0.0), Quat::IDENTITY);
    let mut fall = snowfall(Vec3::NEG_Y);
    fall.noise = 0.3;
    fall.flutter_deg = 4.0;
    let mut snow = window(ctx, fall.clone(), &[bench, ball]);
    run(ctx, &mut snow, 80);
    let before = snow.accumulation().expect("objects").read_atlas(ctx).expect("atlas");
    // Stop the snow; carry the bench 3 m and turn it a quarter about y; roll the ball over.
    snow.set_snowfall(None).expect("stop");
    snow.set_object_pose(0, Vec3::new(1.0, 1.5, 3.0), Quat::from_rotation_y(90f32.to_radians()));
    snow.set_object_pose(1, Vec3::new(2.0, 1.5, 0.0), Quat::from_rotation_x(180f32.to_radians()));
    run(ctx, &mut snow, 10);
    let acc = snow.accumulation().expect("objects");
    let after = acc.read_atlas(ctx).expect("atlas");
    let bake = acc.bake();
    let (mut kept, mut held) = (0usize, 0usize);
    for k in 0..after.len() {
        if bake.owner[k] == 0 && before[k] > 1e-3 {
            held += 1;
            if (after[k] - before[k]).abs() < 1e-6 {
                kept += 1;
            }
        }
    }
    assert!(held > 100, "the bench held snow on {held} texels");
    assert_eq!(kept, held, "every snowy texel of the moved bench keeps its depth");
    // The ball's old top now faces down: beyond any angle of repose, it sheds.
    let top = acc.layout().nearest_texel(bake, 1, Vec3::new(0.0, 0.6, 0.0)).expect("texel");
    assert!(before[top] > 0.5 * RATE * DT * 80.0, "the ball's top held {} m", before[top]);
    assert!(after[top] < 1e-6, "turned over, the ball's old top still holds {} m", after[top]);
}

#[test]
fn trails_refill_only_where_snow_falls() {
    let Some(ctx) = testing::gpu() else { return };
    let roof = object("roof", slab(Vec3::new(3.0, 0.1, 3.0)), Vec3::new(0.0, 2.0, 0.0), Quat::IDENTITY);
    let mut fall = snowfall(Vec3::NEG_Y);
    fall.rate_m_per_s = 0.0;
    let mut snow = window(ctx, fall.clone(), &[roof]);
    // A sphere pressed along z at x = 0 (under the roof for |z| < 1.5) and beyond.
    let press: Vec<snowpack::Deformer> = (0..9).map(|k| snowpack::Deformer::Sphere { center: Vec3::new(0.0, 0.35, -4.0 + k as f32), radius: 0.3 }).collect();
    snow.step(ctx, &press, DT).expect("press");
    fall.rate_m_per_s = RATE;
    snow.set_snowfall(Some(fall)).expect("snow");
    let mut params = snow.params().clone();
    params.refill_m_per_s = 0.02;
    snow.set_refill(params.refill_m_per_s);
    run(ctx, &mut snow, 60);
    let h = snow.read_snow(ctx).expect("snow");
    let under = depth_at(&snow, &h, 0.0, 0.0);
    let open = depth_at(&snow, &h, 0.0, -4.0);
    assert!(under < 0.1, "the trail under the roof stays pressed ({under} m)");
    let want = 0.05 + RATE * DT * 60.0 + 0.02 * DT * 60.0;
    assert!(open > want - 0.02, "the trail in the open refills and gains snowfall ({open} m, want about {want} m)");
}

// ---------------------------------------------------------------------------
// The accumulation's compute passes against their CPU twins on random inputs.

use snowpack::low_level::accumulate::atlas::{AtlasLayout, NO_OWNER};
use snowpack::low_level::accumulate::settle::SettleBuffers;
use snowpack::low_level::accumulate::state::ObjectGpu;
use snowpack::low_level::accumulate::{
    AtlasSurfacePass, IncrementParams, IncrementPass, ScatterParams, ScatterPass, SettleParams, SettlePass, SnowAccumulation, SurfaceParams,
};
use snowpack::low_level::deform::resources::DeformResources;
use snowpack::low_level::deform::update::{UpdateParams, UpdatePass};
use snowpack::low_level::frame::{FrameContext, WindowFrame};
use snowpack::low_level::gpu::GpuTimer;
use snowpack::low_level::gpu::read_buffer;
use snowpack_testkit::cpu;
use snowpack_testkit::testing::Rng;

fn random_objects(rng: &mut Rng, count: usize, extent: f32) -> Vec<SnowObject> {
    (0..count)
        .map(|k| {
            let shape = if rng.range(0.0, 1.0) < 0.6 {
                slab(Vec3::new(rng.range(0.3, 3.0), rng.range(0.05, 1.0), rng.range(0.3, 3.0)))
            } else {
                ObjectShape::Sphere { radius_m: rng.range(0.2, 1.2) }
            };
            let rotation = Quat::from_euler(glam::EulerRot::XYZ, rng.range(-0.8, 0.8), rng.range(-3.0, 3.0), rng.range(-0.8, 0.8));
            let position = Vec3::new(rng.range(0.1, 0.9) * extent, rng.range(0.5, 3.0), rng.range(0.1, 0.9) * extent);
            SnowObject { name: format!("o{k}"), shape, position, rotation, dilate: rng.range(0.0, 1.0) < 0.5 }
        })
        .collect()
}

fn storage_with(ctx: &GpuContext, label: &str, contents: &[u8]) -> wgpu::Buffer {
    use wgpu::util::DeviceExt as _;
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
    })
}

fn read<T: bytemuck::Pod>(ctx: &GpuContext, b: &wgpu::Buffer) -> Vec<T> {
    bytemuck::pod_collect_to_vec(&read_buffer(ctx, b).expect("readback"))
}

fn submit(ctx: &GpuContext, enc: wgpu::CommandEncoder) {
    ctx.queue.submit([enc.finish()]);
    ctx.wait_idle("test").expect("GPU error");
}

fn encoder(ctx: &GpuContext) -> wgpu::CommandEncoder {
    ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("test") })
}

fn close(gpu: &[f32], cpu: &[f32], tol: f32, what: &str, seed: u64) {
    assert_eq!(gpu.len(), cpu.len());
    for (k, (a, b)) in gpu.iter().zip(cpu).enumerate() {
        assert!((a - b).abs() <= tol * (1.0 + b.abs()), "{what}: texel {k}: GPU {a}, CPU {b}; seed {seed}");
    }
}

#[test]
fn scatter_increment_settle_and_surface_match_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("atlas passes");
    let mut rng = Rng::new(seed);
    let objects = random_objects(&mut rng, 6, 10.0);
    let n = 128u32;
    let layout = AtlasLayout::new(&objects, n, 0.01).expect("layout");
    let bake = layout.bake();
    let texels = (n * n) as usize;
    let owned: Vec<usize> = (0..texels).filter(|&k| bake.owner[k] != NO_OWNER).collect();

    // Scatter: random footprints (a third empty) over a 48² occlusion map.
    let occ = 48u32;
    let footprint: Vec<[u16; 4]> = (0..occ * occ)
        .map(|_| {
            if rng.range(0.0, 1.0) < 0.33 {
                return [u16::MAX; 4];
            }
            let k = owned[(rng.next_u64() % owned.len() as u64) as usize];
            let (x, y) = ((k as u32 % n) as u16, (k as u32 / n) as u16);
            let (w, h) = (rng.range(0.0, 4.0) as u16, rng.range(0.0, 4.0) as u16);
            [x, y, (x + w).min(n as u16 - 1), (y + h).min(n as u16 - 1)]
        })
        .collect();
    let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("footprint"),
        size: wgpu::Extent3d { width: occ, height: occ, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: snowpack::low_level::accumulate::occlusion::FOOTPRINT_FORMAT,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    ctx.queue.write_texture(
        texture.as_image_copy(),
        bytemuck::cast_slice(&footprint),
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(occ * 8), rows_per_image: Some(occ) },
        wgpu::Extent3d { width: occ, height: occ, depth_or_array_layers: 1 },
    );
    let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
    let mut hits: Vec<u32> = (0..texels).map(|_| rng.range(0.0, 1e6) as u32).collect();
    let hits_buf = storage_with(ctx, "hits", bytemuck::cast_slice(&hits));
    let sp = ScatterParams { resolution: occ, atlas_resolution: n, frame: rng.next_u64() as u32, noise: rng.range(0.0, 1.0) };
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    ScatterPass::new(&ctx.device, &view, &hits_buf).record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &sp);
    submit(ctx, enc);
    cpu::scatter::scatter(&sp, &footprint, &mut hits);
    let gpu_hits: Vec<u32> = read(ctx, &hits_buf);
    // f32 division may round a weight differently by one unit in 65536 per pixel.
    let worst = gpu_hits.iter().zip(&hits).map(|(a, b)| a.abs_diff(*b)).max().unwrap_or(0);
    assert!(worst <= 16, "scatter hits differ by up to {worst} units; seed {seed}");
    assert!(hits.iter().zip(footprint.iter()).count() > 0);

    // Increment: hits to depth, hits cleared.
    let normal_area = storage_with(ctx, "normal area", bytemuck::cast_slice(&bake.normal_area));
    let fresh_buf = storage_with(ctx, "fresh", &vec![0u8; texels * 4]);
    let ip = IncrementParams { atlas_resolution: n, volume_m3: rng.range(1e-6, 1e-3), _pad: [0; 2] };
    let mut enc = encoder(ctx);
    IncrementPass::new(&ctx.device, &normal_area, &hits_buf, &fresh_buf).record(&mut FrameContext::new(ctx, &mut enc, &mut timer), n, &ip);
    submit(ctx, enc);
    let mut cpu_hits = gpu_hits.clone();
    let mut fresh = vec![0.0f32; texels];
    cpu::increment::increment(&ip, &bake.normal_area, &mut cpu_hits, &mut fresh);
    close(&read::<f32>(ctx, &fresh_buf), &fresh, 1e-5, "increment", seed);
    assert!(read::<u32>(ctx, &hits_buf).iter().all(|&h| h == 0), "hits cleared; seed {seed}");

    // Settle: random accumulation and object rotations.
    let rotations: Vec<glam::Mat4> = objects.iter().map(|o| glam::Mat4::from_quat(o.rotation)).collect();
    let gpu_objects: Vec<ObjectGpu> = objects
        .iter()
        .zip(&rotations)
        .map(|(o, r)| ObjectGpu { rotation: r.to_cols_array_2d(), flags: [u32::from(o.dilate), 0, 0, 0], ..ObjectGpu::default() })
        .collect();
    let objects_buf = storage_with(ctx, "objects", bytemuck::cast_slice(&gpu_objects));
    let owner = storage_with(ctx, "owner", bytemuck::cast_slice(&bake.owner));
    let mut acc: Vec<f32> = (0..texels).map(|_| rng.range(0.0, 0.6)).collect();
    let acc_buf = storage_with(ctx, "acc", bytemuck::cast_slice(&acc));
    let repose = rng.range(20.0, 70.0);
    let stp = SettleParams {
        atlas_resolution: n,
        max_m: rng.range(0.1, 1.0),
        cos_repose: f32::to_radians(repose).cos(),
        falloff: rng.range(0.0, 1.0),
        cos_full: f32::to_radians(repose - 10.0).cos(),
        _pad: [0; 3],
    };
    let mut enc = encoder(ctx);
    SettlePass::new(&ctx.device, &SettleBuffers { objects: &objects_buf, normal_area: &normal_area, owner: &owner, fresh: &fresh_buf, acc: &acc_buf }).record(
        &mut FrameContext::new(ctx, &mut enc, &mut timer),
        n,
        &stp,
    );
    submit(ctx, enc);
    cpu::settle::settle(&stp, &rotations, &bake.normal_area, &bake.owner, &fresh, &mut acc);
    close(&read::<f32>(ctx, &acc_buf), &acc, 1e-5, "settle", seed);
    let held = acc.iter().filter(|&&a| a > 0.0).count();
    let shed = owned.iter().filter(|&&k| acc[k] == 0.0).count();
    // Not vacuous: some texels hold snow and some (steeper than repose) shed it.
    assert!(held > 50 && shed > 50, "settle kept {held} of {} texels and shed {shed}; seed {seed}", owned.len());

    // Surface: dilation and Scharr slopes.
    let surface_buf = storage_with(ctx, "surface", &vec![0u8; texels * 16]);
    let sfp = SurfaceParams { atlas_resolution: n, _pad: [0; 3] };
    let mut enc = encoder(ctx);
    AtlasSurfacePass::new(&ctx.device, &objects_buf, &owner, &acc_buf, &surface_buf).record(&mut FrameContext::new(ctx, &mut enc, &mut timer), n, &sfp);
    submit(ctx, enc);
    let dilate: Vec<bool> = objects.iter().map(|o| o.dilate).collect();
    let cpu_surface = cpu::atlas_surface::atlas_surface(&sfp, &dilate, &bake.owner, &acc);
    let gpu_surface: Vec<[f32; 4]> = read(ctx, &surface_buf);
    let flat = |v: &[[f32; 4]]| v.iter().flatten().copied().collect::<Vec<f32>>();
    close(&flat(&gpu_surface), &flat(&cpu_surface), 1e-5, "atlas surface", seed);
}

#[test]
fn update_with_snowfall_under_objects_matches_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let seed = testing::seed("update with sky");
    let mut rng = Rng::new(seed);
    let extent = rng.range(8.0, 24.0);
    let fall = Snowfall {
        direction: Vec3::new(rng.range(-0.6, 0.6), -1.0, rng.range(-0.6, 0.6)),
        rate_m_per_s: 0.01,
        flutter_deg: rng.range(0.0, 10.0),
        atlas_resolution: 64,
        ..Snowfall::default()
    };
    let params = SnowParams { extent_m: extent, resolution: 64, depth_m: rng.range(0.2, 0.8), snowfall: Some(fall.clone()), ..SnowParams::default() };
    let terrain_src = TerrainSource::Flat { height_m: 0.0 };
    let res = DeformResources::new(&ctx.device, &ctx.queue, &params, &terrain_src);
    let texels = params.texel_count();
    // Flat ground at 0: the update evaluates it from the source.
    let terrain = vec![0.0_f32; texels];
    let mut snow: Vec<u32> = terrain.iter().map(|_| snowpack::low_level::deform::snow_word::deficit_quanta(rng.range(0.0, params.depth_m))).collect();
    let mut fallen: Vec<f32> = (0..texels).map(|_| rng.range(0.0, 0.2)).collect();
    ctx.queue.write_buffer(&res.snow, 0, bytemuck::cast_slice(&snow));
    ctx.queue.write_buffer(&res.fallen, 0, bytemuck::cast_slice(&fallen));
    // The depth technique's window has no footprint buffer; the update reads none.
    assert!(!res.has_stamps());
    let mut stamps = vec![cpu::stamp::STAMP_EMPTY; texels];

    let objects = random_objects(&mut rng, 8, extent);
    let mut acc = SnowAccumulation::new(&ctx.device, &objects, 64, params.resolution, params.texel_m()).expect("objects");
    let mut update = UpdatePass::new(&ctx.device, &res);
    update.bind_sky(&ctx.device, &res, Some(acc.sky_view()));
    let mut timer = GpuTimer::new(&ctx.device, &ctx.queue);
    let mut enc = encoder(ctx);
    // The terrain spans -0.3..0.3 m; the window's corner is at the origin.
    let window = WindowFrame {
        corner: DVec2::ZERO,
        resolution: params.resolution,
        extent_m: extent,
        texel_m: params.texel_m(),
        depth_m: params.depth_m,
        terrain_m: (-0.3, 0.3),
        ..WindowFrame::default()
    };
    acc.upload_poses(&ctx.queue, &window);
    let sky = acc.record_occlusion(&mut FrameContext::new(ctx, &mut enc, &mut timer), &window, &fall);
    let up = UpdateParams {
        origin: [rng.range(-300.0, 300.0) as i32, rng.range(-300.0, 300.0) as i32],
        resolution: params.resolution,
        depth_m: params.depth_m,
        snow_refill_quanta: rng.range(0.0, 500.0) as u32,
        low_m: -2.0,
        high_m: 4.0,
        flags: UpdateParams::USE_FALLEN | UpdateParams::USE_SKY | UpdateParams::LEDGER,
        fall_m: rng.range(0.0, 0.05),
        max_fallen_m: rng.range(0.1, 0.3),
        texel_m: params.texel_m(),
        sky: sky.sky_test(),
        ..UpdateParams::default()
    };
    update.record(&mut FrameContext::new(ctx, &mut enc, &mut timer), &res, &up);
    // The occlusion depth, for the CPU: copied by a compute pass, since GL
    // cannot copy depth textures to buffers.
    let r = params.resolution;
    let staging = storage_with(ctx, "sky copy", &vec![0u8; (r * r * 4) as usize]);
    let (pipeline, bgl) = snowpack::low_level::gpu::layout::compute_pipeline(
        &ctx.device,
        "depth to buffer",
        "@group(0) @binding(0) var depth: texture_2d<f32>;
         @group(0) @binding(1) var<storage, read_write> out: array<f32>;
         @compute @workgroup_size(8, 8)
         fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
             let d = textureDimensions(depth);
             if gid.x < d.x && gid.y < d.y {
                 out[gid.y * d.x + gid.x] = textureLoad(depth, gid.xy, 0).x;
             }
         }",
        &[snowpack::low_level::gpu::layout::depth_texture(0), snowpack::low_level::gpu::layout::storage(1, false)],
    );
    let group = snowpack::low_level::gpu::layout::bind_group(
        &ctx.device,
        "depth to buffer",
        &bgl,
        &[wgpu::BindingResource::TextureView(acc.sky_view()), staging.as_entire_binding()],
    );
    snowpack::low_level::gpu::layout::dispatch(&mut enc, &mut timer, "depth to buffer", &pipeline, &group, (r.div_ceil(8), r.div_ceil(8)));
    submit(ctx, enc);
    let sky_depth: Vec<f32> = read(ctx, &staging);
    let capture = vec![1.0f32; texels];
    let input = cpu::update::UpdateInputs { capture_depth: &capture, sky_depth: &sky_depth, terrain: &terrain };
    let before: Vec<f32> = snow.iter().zip(&fallen).map(|(&w, &l)| snowpack::low_level::deform::snow_word::column_height(w, 0.0, params.depth_m + l)).collect();
    let before_fallen = fallen.clone();
    let mut packed = vec![0u32; texels.div_ceil(2)];
    let cpu_ledger = cpu::update::update(
        &up,
        &input,
        &mut cpu::update::UpdateState { snow: &mut snow, stamps: &mut stamps, fallen: &mut fallen, packed: &mut packed, flags: &mut [] },
    );
    assert_eq!(read::<u32>(ctx, &res.snow), snow, "snow words; seed {seed}");
    close(&read::<f32>(ctx, &res.fallen), &fallen, 1e-5, "fallen", seed);
    // The mass ledger: the refill exactly (the deficits agree), the snowfall
    // to a 0.1 µm step a texel (a fused multiply-add may tip its last bit).
    let gpu_ledger = snowpack::low_level::deform::packed_snow::ledger(&read::<u32>(ctx, &res.packed));
    assert_eq!(gpu_ledger.refill_q, cpu_ledger.refill_q, "refill counted; seed {seed}");
    assert!(cpu_ledger.refill_q > 0 || up.snow_refill_quanta == 0, "no refill counted; seed {seed}");
    assert!(
        gpu_ledger.snowfall_fine.abs_diff(cpu_ledger.snowfall_fine) <= texels as u64 / 8,
        "snowfall counted: GPU {gpu_ledger:?}, CPU {cpu_ledger:?}; seed {seed}"
    );
    // What the counts say fell is what the texels gained.
    let gained: f64 = fallen.iter().zip(&before_fallen).map(|(&a, &b)| f64::from(a - b)).sum();
    let counted = cpu_ledger.snowfall_fine as f64 / f64::from(snowpack::low_level::deform::packed_snow::LEDGER_FINE_PER_M);
    assert!((counted - gained).abs() <= 1e-7 * texels as f64, "snowfall counted {counted} m, gained {gained} m; seed {seed}");
    let hidden = (0..r)
        .flat_map(|i| (0..r).map(move |j| (i, j)))
        .filter(|&(i, j)| {
            let s = cpu::window::storage_index(up.origin, r, i, j);
            cpu::update::sky_visible(&up, &sky_depth, i, j, before[s]) == 0.0
        })
        .count();
    assert!(hidden > texels / 200 && hidden < texels - texels / 200, "{hidden} of {texels} texels under objects; seed {seed}");
}

#[test]
fn a_mesh_object_gathers_snow_and_shelters_the_ground() {
    let Some(ctx) = testing::gpu() else { return };
    // A 2 x 2 m sheet of eight triangles, no UVs (a chart per triangle), 1 m up.
    let mut positions = Vec::new();
    for z in 0..3 {
        for x in 0..3 {
            positions.push(Vec3::new(x as f32 - 1.0, 0.0, z as f32 - 1.0));
        }
    }
    let mut indices = Vec::new();
    for z in 0..2u32 {
        for x in 0..2u32 {
            let a = z * 3 + x;
            indices.extend_from_slice(&[a, a + 3, a + 1, a + 1, a + 3, a + 4]);
        }
    }
    let mesh = snowpack::low_level::accumulate::ObjectMesh { positions, normals: vec![], uvs: None, indices };
    let sheet = object("sheet", ObjectShape::Mesh(std::sync::Arc::new(mesh)), Vec3::new(0.0, 1.0, 0.0), Quat::IDENTITY);
    let mut snow = window(ctx, snowfall(Vec3::NEG_Y), &[sheet]);
    let frames = 100;
    run(ctx, &mut snow, frames);
    let fallen = RATE * DT * frames as f32;
    let h = snow.read_snow(ctx).expect("snow");
    assert!((depth_at(&snow, &h, 0.0, 0.0) - DEPTH_M).abs() < 1e-4, "under the sheet");
    assert!((depth_at(&snow, &h, 3.0, 3.0) - DEPTH_M - fallen).abs() < 1e-4, "beside it");
    let acc = snow.accumulation().expect("objects");
    let stats = acc.stats(&acc.read_atlas(ctx).expect("atlas"));
    assert!((stats[0].mean_m - fallen).abs() < 0.15 * fallen, "the sheet holds {:?}, want about {fallen} m", stats[0]);
}
