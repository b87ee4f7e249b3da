//! Drawing the snow into a game's own pass (`SnowGround`) and sampling it from
//! a game's own shader (`SNOW_SAMPLING_WGSL`), against the CPU twin.

use glam::{DVec2, Mat4, Vec2, Vec3, Vec4};
use snowpack::low_level::GpuContextExt;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::gpu::read_buffer;
use snowpack::low_level::render::ground::{SnowSampling, snow_sampling_wgsl};
use snowpack::low_level::{SnowGroundDescriptorExt, SnowWindowUniformExt};
use snowpack::{Deformer, GpuContext, NoiseTerrain, SnowDeformation, SnowParams, TerrainSource};
use snowpack::{GroundCamera, SNOW_SAMPLING_GROUP, SNOW_SAMPLING_WGSL, SnowGround, SnowGroundDescriptor, SnowWindowUniform};
use snowpack_testkit::cpu::snow_sampling::SampledSurface;
use snowpack_testkit::testing::{self, Rng};

/// The GPU tests here take turns (on GL a submission holds the adapter's context).
static GPU_TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn gpu_turn() -> std::sync::MutexGuard<'static, ()> {
    GPU_TURN.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Presses a sphere (bottom 0.1 m above flat ground at 0, under 0.5 m of snow)
/// along x from -4 to 4 at z = 0: a trench 0.4 m deep, about 0.6 m wide.
fn trench(ctx: &GpuContext, params: SnowParams, terrain: TerrainSource) -> SnowDeformation {
    let mut snow = SnowDeformation::new(ctx, params, terrain, DVec2::ZERO).expect("window");
    for k in 0..=40 {
        let x = -4.0 + 0.2 * k as f32;
        snow.step(ctx, &[Deformer::Sphere { center: Vec3::new(x, 0.6, 0.0), radius: 0.5 }], 1.0 / 60.0).expect("frame");
    }
    snow.finish(ctx).expect("finish");
    snow
}

const SIZE: u32 = 256;
const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

fn target(ctx: &GpuContext, format: wgpu::TextureFormat) -> wgpu::Texture {
    ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("caller target"),
        size: wgpu::Extent3d { width: SIZE, height: SIZE, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    })
}

/// The depth target's values, row-major, read with `textureLoad` in a compute
/// shader (GL cannot copy depth textures to buffers).
fn read_depth(ctx: &GpuContext, texture: &wgpu::Texture) -> Vec<f32> {
    const READ_DEPTH_WGSL: &str = r"
@group(0) @binding(0) var depth_target: texture_2d<f32>;
@group(0) @binding(1) var<storage, read_write> values: array<f32>;
@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(depth_target);
    if id.x < size.x && id.y < size.y {
        values[id.y * size.x + id.x] = textureLoad(depth_target, vec2<i32>(id.xy), 0).r;
    }
}
";
    let device = &ctx.device;
    let (pipeline, layout) = snowpack::low_level::gpu::layout::compute_pipeline(
        device,
        "read depth",
        READ_DEPTH_WGSL,
        &[snowpack::low_level::gpu::layout::depth_texture(0), snowpack::low_level::gpu::layout::storage(1, false)],
    );
    let values = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("depth values"),
        size: u64::from(SIZE * SIZE * 4),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let view = texture.create_view(&wgpu::TextureViewDescriptor { aspect: wgpu::TextureAspect::DepthOnly, ..Default::default() });
    let group =
        snowpack::low_level::gpu::layout::bind_group(device, "read depth", &layout, &[wgpu::BindingResource::TextureView(&view), values.as_entire_binding()]);
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(SIZE / 16, SIZE / 16, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    bytemuck::pod_collect_to_vec(&read_buffer(ctx, &values).expect("read depth"))
}

/// The colour target's RGBA8 texels, row-major.
fn read_texture(ctx: &GpuContext, texture: &wgpu::Texture) -> Vec<u8> {
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("target copy"),
        size: u64::from(SIZE * SIZE * 4),
        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(SIZE * 4), rows_per_image: Some(SIZE) },
        },
        wgpu::Extent3d { width: SIZE, height: SIZE, depth_or_array_layers: 1 },
    );
    ctx.queue.submit([encoder.finish()]);
    read_buffer(ctx, &buffer).expect("read target")
}

/// The caller's own object: a horizontal red plate, drawn with the caller's pipeline.
const PLATE_WGSL: &str = r"
@group(0) @binding(0) var<uniform> view_proj: mat4x4<f32>;
@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    // x in [-3, -1], z in [-1, 1], at y = 0.3: below untouched snow (0.5), above the trench floor (0.1).
    var corners = array<vec2<f32>, 6>(vec2(-3.0, -1.0), vec2(-3.0, 1.0), vec2(-1.0, 1.0), vec2(-3.0, -1.0), vec2(-1.0, 1.0), vec2(-1.0, -1.0));
    let c = corners[vi];
    return view_proj * vec4<f32>(c.x, 0.3, c.y, 1.0);
}
@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0, 0.0, 0.0, 1.0);
}
";
const PLATE_Y: f32 = 0.3;

struct Plate {
    pipeline: wgpu::RenderPipeline,
    group: wgpu::BindGroup,
}

fn plate(ctx: &GpuContext, view_proj: Mat4) -> Plate {
    use wgpu::util::DeviceExt as _;
    let device = &ctx.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("plate"), source: wgpu::ShaderSource::Wgsl(PLATE_WGSL.into()) });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("plate"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        }],
    });
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("plate camera"),
        contents: bytemuck::cast_slice(&view_proj.to_cols_array()),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("plate"),
        layout: &layout,
        entries: &[wgpu::BindGroupEntry { binding: 0, resource: buffer.as_entire_binding() }],
    });
    let pipeline_layout =
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("plate"), bind_group_layouts: &[Some(&layout)], immediate_size: 0 });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("plate"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState { module: &module, entry_point: Some("vs_main"), compilation_options: Default::default(), buffers: &[] },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Greater),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(COLOR.into())],
        }),
        multiview_mask: None,
        cache: None,
    });
    Plate { pipeline, group }
}

/// The caller's frame: clear colour (sky) and depth (reverse-Z: 0), draw the
/// plate (if any), then the snow seen by `camera`, into the caller's targets.
fn caller_frame(
    ctx: &GpuContext,
    (ground, snow, camera): (&mut SnowGround, &SnowDeformation, &GroundCamera),
    plate: Option<&Plate>,
    color: &wgpu::Texture,
    depth: &wgpu::Texture,
) {
    let color_view = color.create_view(&wgpu::TextureViewDescriptor::default());
    let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("caller frame") });
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("caller pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color { r: 0.35, g: 0.5, b: 0.75, a: 1.0 }), store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if let Some(p) = plate {
            pass.set_pipeline(&p.pipeline);
            pass.set_bind_group(0, &p.group, &[]);
            pass.draw(0..6, 0..1);
        }
        ground.draw(&mut pass, &ctx.queue, snow, camera);
    }
    ctx.queue.submit([encoder.finish()]);
}

/// Orthographic, looking straight down at x, z in [-8, 8] (row down the image = +z),
/// reverse-Z over heights -1..3 m: depth = (y + 1) / 4.
fn top_down() -> Mat4 {
    Mat4::from_cols(Vec4::new(1.0 / 8.0, 0.0, 0.0, 0.0), Vec4::new(0.0, 0.0, 0.25, 0.0), Vec4::new(0.0, -1.0 / 8.0, 0.0, 0.0), Vec4::new(0.0, 0.0, 0.25, 1.0))
}

/// World (x, z) at the centre of pixel (column, row) of [`top_down`].
fn pixel_xz(px: u32, py: u32) -> Vec2 {
    Vec2::new((px as f32 + 0.5) / SIZE as f32 * 16.0 - 8.0, (py as f32 + 0.5) / SIZE as f32 * 16.0 - 8.0)
}

fn rgb(image: &[u8], px: u32, py: u32) -> [u8; 3] {
    let k = ((py * SIZE + px) * 4) as usize;
    [image[k], image[k + 1], image[k + 2]]
}

fn luma(c: [u8; 3]) -> f32 {
    0.2126 * f32::from(c[0]) + 0.7152 * f32::from(c[1]) + 0.0722 * f32::from(c[2])
}

fn save_png(name: &str, image: &[u8]) -> String {
    let path = format!("{}/{name}.png", env!("CARGO_TARGET_TMPDIR"));
    image::save_buffer(&path, image, SIZE, SIZE, image::ExtendedColorType::Rgba8).expect("png");
    path
}

#[test]
fn ground_draws_into_the_callers_pass_and_shares_its_depth() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let params = SnowParams { extent_m: 16.0, resolution: 256, depth_m: 0.5, ..SnowParams::default() };
    let snow = trench(ctx, params, TerrainSource::Flat { height_m: 0.0 });
    let terrain = snow.terrain().clone();
    let above = snowpack_testkit::cpu::snow_sampling::above_ground(&snow.read_snow_words(ctx).expect("words"));
    let cpu = SampledSurface { window: SnowWindowUniform::new(&snow), above: &above, terrain: &terrain };

    // The caller's formats and reverse-Z depth; the grid at one quad per texel.
    let desc = SnowGroundDescriptor::new(COLOR).with_depth(DEPTH, wgpu::CompareFunction::Greater).with_grid_quads(256);
    let mut ground = SnowGround::new(&ctx.device, &snow, &desc);
    let view_proj = top_down();
    let camera = GroundCamera::new(view_proj, Vec3::new(0.0, 10.0, 0.0));
    let (color, depth) = (target(ctx, COLOR), target(ctx, DEPTH));
    let plate = plate(ctx, view_proj);
    caller_frame(ctx, (&mut ground, &snow, &camera), Some(&plate), &color, &depth);
    ctx.check("drawing the ground").expect("no GPU error");
    let image = read_texture(ctx, &color);
    let depths = read_depth(ctx, &depth);
    eprintln!("top-down frame: {}", save_png("ground-top-down", &image));

    let on_plate = |xz: Vec2| (-3.0..=-1.0).contains(&xz.x) && (-1.0..=1.0).contains(&xz.y);
    let (mut red_ok, mut snow_ok, mut wrong) = (0, 0, Vec::new());
    let (mut worst, mut sum, mut n) = (0.0f32, 0.0f32, 0);
    for py in 0..SIZE {
        for px in 0..SIZE {
            let xz = pixel_xz(px, py);
            let h = cpu.height(xz);
            let c = rgb(&image, px, py);
            let red = c == [255, 0, 0];
            if on_plate(xz) && xz.x > -2.95 && xz.x < -1.05 && xz.y.abs() < 0.95 {
                // The plate shows where the snow is below it, the snow where it is above
                // (2 cm band: the grid is linear between vertices, the twin bilinear between texel centres).
                if h < PLATE_Y - 0.02 {
                    if red { red_ok += 1 } else { wrong.push((xz, h, c)) }
                } else if h > PLATE_Y + 0.02 {
                    if red { wrong.push((xz, h, c)) } else { snow_ok += 1 }
                }
            } else if !on_plate(xz) {
                assert!(!red, "plate colour outside the plate at {xz}");
                // Depth written by the ground is its height: y = 4 depth - 1.
                let y = 4.0 * depths[(py * SIZE + px) as usize] - 1.0;
                let e = (y - h).abs();
                worst = worst.max(e);
                sum += e;
                n += 1;
            }
        }
    }
    eprintln!(
        "plate: {red_ok} pixels over the trench, {snow_ok} hidden by snow; ground depth vs twin: mean {:.2e} m, worst {worst:.3} m",
        sum / n.max(1) as f32
    );
    assert!(wrong.is_empty(), "{} plate pixels wrong, e.g. {:?}", wrong.len(), &wrong[..wrong.len().min(5)]);
    assert!(red_ok > 300 && snow_ok > 300, "plate test covered too little: {red_ok} red, {snow_ok} snow");
    // One grid vertex per texel corner: within a millimetre on average; the
    // worst is on the trench's steep walls, where linear-between-corners and
    // bilinear-between-centres part most (a fraction of the 0.4 m wall over a texel).
    let mean_error = sum / n as f32;
    assert!(mean_error < 2e-3, "ground depth differs from the surface by {mean_error} m on average");
    assert!(worst < 0.05, "ground depth differs from the surface by up to {worst} m");

    // Depth over the trench floor and beside it, as geometry predicts.
    let depth_at = |x: f32, z: f32| {
        let (px, py) = (((x + 8.0) / 16.0 * SIZE as f32) as u32, ((z + 8.0) / 16.0 * SIZE as f32) as u32);
        4.0 * depths[(py * SIZE + px) as usize] - 1.0
    };
    // (Hanak's rim remap shows the 0.1 m left under the sphere close to the ground.)
    let (floor, beside) = (depth_at(2.0, 0.0), depth_at(2.0, 2.0));
    let (floor_cpu, beside_cpu) = (cpu.height(pixel_xz(160, 128)), cpu.height(pixel_xz(160, 160)));
    assert!((floor - floor_cpu).abs() < 0.01 && floor < 0.1, "trench floor drawn at {floor} m, displayed surface {floor_cpu} m");
    // (The remap shows untouched snow 1.5% above its rest depth: 0.508 m.)
    assert!((beside - beside_cpu).abs() < 0.002 && (beside - 0.5).abs() < 0.01, "untouched snow drawn at {beside} m, displayed surface {beside_cpu} m");
    assert!(beside - floor > 0.4, "trench {floor} m vs untouched {beside} m");

    // Colour: untouched snow is bright, near-white and a little blue; the
    // trench floor (pressed to the ground, same normal) is clearly darker.
    let mean = |xs: std::ops::Range<u32>, ys: std::ops::Range<u32>| {
        let mut s = [0.0f32; 3];
        let mut count = 0.0;
        for py in ys.clone() {
            for px in xs.clone() {
                let c = rgb(&image, px, py);
                for k in 0..3 {
                    s[k] += f32::from(c[k]);
                }
                count += 1.0;
            }
        }
        s.map(|v| v / count)
    };
    // Pixels 158..190 are x 1.9..3.9; rows 127..129 straddle z = 0, rows 150..160 are z 1.4..2.
    let floor_c = mean(158..190, 127..129);
    let fresh_c = mean(158..190, 150..160);
    eprintln!("fresh snow {fresh_c:?}, trench floor {floor_c:?}");
    let l = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    assert!(l(fresh_c) > 190.0 && fresh_c[2] >= fresh_c[0], "untouched snow is not bright blue-white: {fresh_c:?}");
    assert!(l(fresh_c) - l(floor_c) > 25.0, "trench floor {floor_c:?} hardly differs from fresh snow {fresh_c:?}");

    // The same snow seen in perspective, as a player would: the trench is visible.
    // Steep enough (about 50 degrees down) that the trench's near wall does not hide its floor.
    let eye = Vec3::new(1.0, 5.0, -4.5);
    let view_proj = snowpack::Camera { position: eye, target: Vec3::new(0.0, 0.0, 0.5), fov_deg: 55.0 }.view_proj(1.0);
    caller_frame(ctx, (&mut ground, &snow, &GroundCamera::new(view_proj, eye)), None, &color, &depth);
    let image = read_texture(ctx, &color);
    eprintln!("perspective frame: {}", save_png("ground-perspective", &image));
    let project = |p: Vec3| {
        let c = view_proj * p.extend(1.0);
        let ndc = c.truncate() / c.w;
        (((ndc.x * 0.5 + 0.5) * SIZE as f32) as u32, ((0.5 - ndc.y * 0.5) * SIZE as f32) as u32)
    };
    let (tx, ty) = project(Vec3::new(-1.0, cpu.height(Vec2::new(-1.0, 0.0)), 0.0));
    let (ux, uy) = project(Vec3::new(-1.0, cpu.height(Vec2::new(-1.0, 1.5)), 1.5));
    let (trench_l, fresh_l) = (luma(rgb(&image, tx, ty)), luma(rgb(&image, ux, uy)));
    assert!(fresh_l - trench_l > 20.0, "perspective: trench {trench_l} vs untouched {fresh_l}");
}

/// A game's compute shader: its own bindings in group 0, the exported module's in group 1.
const GAME_PROBE_WGSL: &str = r"
@group(0) @binding(0) var<storage, read> probes: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read_write> samples: array<vec4<f32>>;   // height, depth, compaction, 0
@group(0) @binding(2) var<storage, read_write> sampled_normals: array<vec4<f32>>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&probes) {
        return;
    }
    let xz = probes[id.x];
    samples[id.x] = vec4<f32>(snow_height(xz), snow_depth(xz), snow_compaction(xz), 0.0);
    sampled_normals[id.x] = vec4<f32>(snow_normal(xz), 0.0);
}
";

#[test]
fn a_games_shader_samples_the_snow_like_the_cpu() {
    let Some(ctx) = testing::gpu() else { return };
    let _turn = gpu_turn();
    let seed = testing::seed("ground sampling");
    let mut rng = Rng::new(seed);
    // Rolling terrain, no rims or blur (so the displayed surface is the
    // persistent snow and compaction can be checked against `read_snow`).
    let params = SnowParams { extent_m: 16.0, resolution: 128, depth_m: 0.5, elevation: 0.0, blur: false, ..SnowParams::default() };
    let terrain = TerrainSource::Noise(NoiseTerrain { seed: 5, base_m: 0.0, amplitude_m: 0.6, wavelength_m: 10.0 });
    let mut snow = SnowDeformation::new(ctx, params, terrain, DVec2::ZERO).expect("window");
    // Spheres pressing into the snow on the terrain, then the window slides
    // (a nonzero, non-multiple-of-resolution origin) and presses once more.
    for k in 0..=30 {
        let x = -4.0 + 0.25 * k as f32;
        let y = snow.terrain().height_at(x, 0.5) + 0.55;
        snow.step(ctx, &[Deformer::Sphere { center: Vec3::new(x, y, 0.5), radius: 0.5 }], 1.0 / 60.0).expect("frame");
    }
    snow.set_center(DVec2::new(2.3, -1.7));
    let y = snow.terrain().height_at(4.0, -3.0) + 0.4;
    snow.step(ctx, &[Deformer::Sphere { center: Vec3::new(4.0, y, -3.0), radius: 0.6 }], 1.0 / 60.0).expect("frame");
    snow.finish(ctx).expect("finish");

    let mut sampling = SnowSampling::new(&ctx.device, &snow, wgpu::ShaderStages::COMPUTE);
    sampling.update(&ctx.queue, &snow);
    let window = SnowWindowUniform::new(&snow);
    assert_ne!(window.origin_texel(), [0, 0], "the window did not slide");
    let corner = Vec2::from(window.corner());
    let extent = 16.0;
    // Random points inside the window and up to 3 m beyond it, texel centres and the window's own corners.
    let mut probes: Vec<Vec2> = (0..2000)
        .map(|_| {
            if rng.range(0.0, 1.0) < 0.8 {
                corner + Vec2::new(rng.range(0.0, extent), rng.range(0.0, extent))
            } else {
                corner + Vec2::new(rng.range(-3.0, extent + 3.0), rng.range(-3.0, extent + 3.0))
            }
        })
        .collect();
    probes.extend((0..50).map(|_| corner + (Vec2::new((rng.range(0.0, 128.0)).floor(), (rng.range(0.0, 128.0)).floor()) + 0.5) * window.texel_m()));
    probes.extend([corner, corner + Vec2::new(extent, 0.0), corner + Vec2::splat(extent), corner - 0.01]);

    let source = format!("{SNOW_SAMPLING_WGSL}\n{GAME_PROBE_WGSL}");
    let device = &ctx.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("game probe"), source: wgpu::ShaderSource::Wgsl(source.into()) });
    let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    };
    let game_layout = device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("game"), entries: &[storage(0, true), storage(1, false), storage(2, false)] });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("game probe"),
        bind_group_layouts: &[Some(&game_layout), Some(sampling.layout())],
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("game probe"),
        layout: Some(&layout),
        module: &module,
        entry_point: Some("probe"),
        compilation_options: Default::default(),
        cache: None,
    });
    let buffer = |label, size: u64, usage| device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false });
    let n = probes.len() as u64;
    let probe_buf = buffer("probes", n * 8, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST);
    ctx.queue.write_buffer(&probe_buf, 0, bytemuck::cast_slice(&probes));
    let out = buffer("samples", n * 16, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
    let out_n = buffer("normals", n * 16, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("game"),
        layout: &game_layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: probe_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: out.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: out_n.as_entire_binding() },
        ],
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.set_bind_group(SNOW_SAMPLING_GROUP, sampling.bind_group(), &[]);
        pass.dispatch_workgroups((n as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    ctx.check("game probe").expect("no GPU error");
    let gpu: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &out).expect("samples"));
    let gpu_n: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &out_n).expect("normals"));

    // The CPU reference from blocking reads of the same state.
    let (heights, _normals) = snow.read_surface(ctx).expect("surface");
    let persistent = snow.read_snow(ctx).expect("snow");
    let ground = snow.read_terrain(ctx).expect("terrain");
    let (worst_k, worst) =
        heights.iter().zip(&persistent).map(|(a, b)| (a - b).abs()).enumerate().fold((0, 0.0f32), |m, (k, e)| if e > m.1 { (k, e) } else { m });
    // The displayed height is an f16 above the terrain: within 2^-11 of 0.5 m.
    assert!(
        worst < 3e-4,
        "without rims and blur the displayed surface is the persistent snow: texel {worst_k} {} vs {}",
        heights[worst_k],
        persistent[worst_k]
    );
    let above = snowpack_testkit::cpu::snow_sampling::above_ground(&snow.read_snow_words(ctx).expect("words"));
    let cpu = SampledSurface { window, above: &above, terrain: snow.terrain() };
    // Compaction from the persistent snow and terrain texels, independently of the twin.
    let res = 128usize;
    let compaction_from_snow = |xz: Vec2| -> f32 {
        if !cpu.inside(xz) {
            return 0.0;
        }
        let t = ((xz - corner) / window.texel_m() - 0.5).clamp(Vec2::ZERO, Vec2::splat(127.0));
        let (j0, i0) = (t.x.floor() as usize, t.y.floor() as usize);
        let (j1, i1) = ((j0 + 1).min(res - 1), (i0 + 1).min(res - 1));
        let f = t - t.floor();
        let pressed = |i: usize, j: usize| ground[i * res + j] + window.rest_depth_m() - persistent[i * res + j];
        let p = (pressed(i0, j0) * (1.0 - f.x) + pressed(i0, j1) * f.x) * (1.0 - f.y) + (pressed(i1, j0) * (1.0 - f.x) + pressed(i1, j1) * f.x) * f.y;
        (p / window.rest_depth_m()).clamp(0.0, 1.0)
    };

    // Tolerances: heights are f32 bilinear blends of metres (and the noise
    // terrain, the same operations on both sides): 1e-4 m. Normals are
    // snorm16-packed: 1e-3 per component. Compaction is a height difference
    // over the 0.5 m depth: 1e-3.
    let (mut inside, mut pressed, mut outside) = (0, 0, 0);
    for (k, &xz) in probes.iter().enumerate() {
        let [h, d, c, _] = gpu[k];
        let n = Vec3::new(gpu_n[k][0], gpu_n[k][1], gpu_n[k][2]);
        let ctx_msg = || format!("seed {seed}: probe {k} at {xz} (inside: {})", cpu.inside(xz));
        assert!((h - cpu.height(xz)).abs() < 1e-4, "{}: height {h} vs CPU {}", ctx_msg(), cpu.height(xz));
        assert!((d - cpu.depth(xz)).abs() < 1e-4, "{}: depth {d} vs CPU {}", ctx_msg(), cpu.depth(xz));
        assert!((c - cpu.compaction(xz)).abs() < 1e-3, "{}: compaction {c} vs CPU {}", ctx_msg(), cpu.compaction(xz));
        assert!((c - compaction_from_snow(xz)).abs() < 1e-3, "{}: compaction {c} vs persistent snow {}", ctx_msg(), compaction_from_snow(xz));
        assert!((n - cpu.normal(xz)).abs().max_element() < 1e-3, "{}: normal {n} vs CPU {}", ctx_msg(), cpu.normal(xz));
        assert!((n.length() - 1.0).abs() < 1e-4, "{}: normal not unit", ctx_msg());
        if cpu.inside(xz) {
            inside += 1;
            pressed += usize::from(c > 0.5);
        } else {
            outside += 1;
            // Outside: the untouched rest surface.
            let rest = snow.terrain().height_at(xz.x, xz.y) + 0.5;
            assert!((h - rest).abs() < 1e-4 && c == 0.0 && (d - 0.5).abs() < 1e-4, "{}: outside not at rest", ctx_msg());
        }
    }
    eprintln!("{inside} probes inside ({pressed} pressed over half the depth), {outside} outside");
    assert!(pressed >= 5 && outside >= 100, "seed {seed}: the probes missed the trench or the outside");
}

/// A tiny user vertex shader, as a game would write it, using the module's functions.
const USER_VERTEX_WGSL: &str = r"
struct Camera { view_proj: mat4x4<f32> }
@group(0) @binding(0) var<uniform> user_camera: Camera;
struct Out { @builtin(position) clip: vec4<f32>, @location(0) normal: vec3<f32>, @location(1) pressed: f32 }
@vertex
fn user_vs(@location(0) xz: vec2<f32>) -> Out {
    var out: Out;
    out.clip = user_camera.view_proj * vec4<f32>(xz.x, snow_height(xz), xz.y, 1.0);
    out.normal = snow_normal(xz);
    out.pressed = snow_compaction(xz) + snow_depth(xz) * 0.0;
    return out;
}
";

fn validate(source: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    module
}

fn snow_bindings(module: &naga::Module) -> Vec<(String, u32, u32)> {
    let mut out: Vec<(String, u32, u32)> = module
        .global_variables
        .iter()
        .filter_map(|(_, v)| v.binding.as_ref().map(|b| (v.name.clone().unwrap_or_default(), b.group, b.binding)))
        .filter(|(name, _, _)| name != "user_camera")
        .collect();
    out.sort_by_key(|b| b.2);
    out
}

#[test]
fn the_exported_module_validates_in_a_user_shader() {
    let names = ["snow_window", "snow_terrain", "heightmap", "snow_words"];
    // As exported (group 1) and moved to group 3.
    for (group, module_source) in [(SNOW_SAMPLING_GROUP, SNOW_SAMPLING_WGSL.to_owned()), (3, snow_sampling_wgsl(3))] {
        let module = validate(&format!("{module_source}\n{USER_VERTEX_WGSL}"));
        let expected: Vec<(String, u32, u32)> = names.iter().enumerate().map(|(k, n)| ((*n).to_owned(), group, k as u32)).collect();
        assert_eq!(snow_bindings(&module), expected);
        assert!(module.entry_points.iter().any(|e| e.name == "user_vs"));
        for f in ["snow_height", "snow_normal", "snow_compaction", "snow_depth"] {
            assert!(module.functions.iter().any(|(_, g)| g.name.as_deref() == Some(f)), "no `{f}`");
        }
    }
    // The group rewrite touches the module's bindings and nothing else.
    assert_eq!(snow_sampling_wgsl(SNOW_SAMPLING_GROUP), SNOW_SAMPLING_WGSL);
    assert_eq!(snow_sampling_wgsl(3).matches("@group(3)").count(), 4);
    // The ground pass is built on the exported module, verbatim.
    assert!(snowpack::low_level::shaders::GROUND.starts_with(SNOW_SAMPLING_WGSL.trim_end()));
}
