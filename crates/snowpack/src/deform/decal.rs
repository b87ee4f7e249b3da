//! Decals (Wasmut 2019, sections 2.2.3 and 4.2.3): each actor's last N
//! contacts with the snow, drawn as quads oriented to the terrain normal with
//! a procedural footprint texture and, beyond Wasmut's version, a normal map,
//! into a window-local layer (`decal.wgsl`). Decals never change the snow
//! height: they are a look, not a deformation.

use std::collections::VecDeque;

use bytemuck::{Pod, Zeroable};
use glam::{DVec2, Vec3};

use crate::deform::shape::DeformerExt;
use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::terrain::TerrainSourceExt;
use crate::{Deformer, TerrainSource, shaders};

/// Format of the decal layer: normal x, z, tint, coverage.
pub const DECAL_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Side of the generated footprint texture (texels).
pub const FOOTPRINT_SIDE: u32 = 64;
/// Contacts kept per actor by default (Wasmut keeps 1000).
pub const DEFAULT_PER_ACTOR: usize = 1000;
/// Most contacts kept over all actors (2 MiB of [`Decal`]s): each actor
/// keeps its `per_actor` while they fit, an equal share when more actors
/// than that press the snow. A crowd of 16,384 would otherwise hold 500 MiB
/// of contacts, filling as it walks (the stress test measured it).
pub const DECAL_BUDGET: usize = 1 << 16;

/// Uniforms of `decal.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DecalParams {
    /// World (x, z) of the window's corner relative to the ring's anchor (m).
    pub corner_m: [f32; 2],
    /// Side of the window (m).
    pub extent_m: f32,
    /// Padding.
    pub _pad: f32,
}

/// One contact: where, how big, which way, on what slope.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct Decal {
    /// (x, z relative to the anchor (m), radius (m), yaw (rad)).
    pub place: [f32; 4],
    /// (terrain normal xyz, fade 0..1).
    pub normal: [f32; 4],
}

/// The footprint texture: a rotation-invariant sphere print (a bowl with a
/// soft raised lip, rough at the edge) as normal map (rg), tint (b) and
/// coverage (a). `side` x `side`, row-major RGBA8.
#[must_use]
pub fn footprint_texture(side: u32) -> Vec<[u8; 4]> {
    // Height of the print along the radius r in [0, 1]: a bowl to 0.75, a lip to 1.
    let profile = |r: f32| -> f32 {
        if r < 0.75 {
            let t = r / 0.75;
            -(1.0 - t * t)
        } else {
            let t = (r - 0.75) / 0.25;
            0.25 * (std::f32::consts::PI * t).sin()
        }
    };
    let rough = |x: u32, y: u32| (crate::terrain::lattice_hash(x as i32, y as i32, 77) >> 24) as f32 / 255.0;
    let h = 2.0 / side as f32;
    let mut out = Vec::with_capacity((side * side) as usize);
    for y in 0..side {
        for x in 0..side {
            let u = (x as f32 + 0.5) / side as f32 * 2.0 - 1.0;
            let v = (y as f32 + 0.5) / side as f32 * 2.0 - 1.0;
            let r = (u * u + v * v).sqrt();
            let at = |du: f32, dv: f32| profile(((u + du).powi(2) + (v + dv).powi(2)).sqrt().min(1.0)) * 0.35;
            let (dx, dy) = ((at(h, 0.0) - at(-h, 0.0)) / (2.0 * h), (at(0.0, h) - at(0.0, -h)) / (2.0 * h));
            let n = Vec3::new(-dx, -dy, 1.0).normalize();
            // Coverage fades over the lip, broken up by a rough brush.
            let edge = ((1.0 - r) / 0.2).clamp(0.0, 1.0);
            let alpha = (edge * (0.75 + 0.25 * rough(x, y))).clamp(0.0, 1.0);
            let tint = if r < 0.75 { 0.55 + 0.25 * (r / 0.75) } else { 0.85 + 0.15 * ((r - 0.75) / 0.25) };
            let to8 = |c: f32| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            out.push([to8(n.x * 0.5 + 0.5), to8(n.y * 0.5 + 0.5), to8(tint), to8(alpha)]);
        }
    }
    out
}

/// Each actor's last contacts, in world space relative to an anchor (so
/// `f32` stays precise far from the origin).
#[derive(Clone, Debug)]
pub struct DecalRing {
    per_actor: usize,
    /// Contacts each actor keeps now: `per_actor`, or the actors' equal
    /// share of [`DECAL_BUDGET`].
    kept: usize,
    anchor: DVec2,
    actors: Vec<VecDeque<Decal>>,
    last: Vec<Option<DVec2>>,
    dirty: bool,
}

impl DecalRing {
    /// An empty ring keeping `per_actor` contacts per actor.
    #[must_use]
    pub fn new(per_actor: usize, anchor: DVec2) -> Self {
        let per_actor = per_actor.max(1);
        Self { per_actor, kept: per_actor, anchor, actors: Vec::new(), last: Vec::new(), dirty: false }
    }

    /// Contacts each actor keeps now (`per_actor`, or fewer when many
    /// actors share [`DECAL_BUDGET`]).
    #[cfg(test)]
    fn kept_per_actor(&self) -> usize {
        self.kept
    }

    /// Makes room for `actors` actors within [`DECAL_BUDGET`]: each keeps
    /// its share, its oldest contacts dropped and its ring's memory given
    /// back when the share shrinks.
    fn make_room(&mut self, actors: usize) {
        self.actors.resize_with(actors, VecDeque::new);
        self.last.resize(actors, None);
        self.kept = (DECAL_BUDGET / actors.max(1)).clamp(1, self.per_actor);
        for ring in &mut self.actors {
            if ring.len() > self.kept {
                ring.drain(..ring.len() - self.kept);
                self.dirty = true;
            }
            if ring.capacity() > self.kept {
                ring.shrink_to(self.kept);
            }
        }
    }

    /// Records this frame's contacts: an actor whose lowest point is below the
    /// rest snow height under it leaves a decal once it has moved half its
    /// radius since its last one. `deformers[k]` is actor k in every frame.
    pub fn observe(&mut self, deformers: &[Deformer], terrain: &TerrainSource, depth_m: f32) {
        if self.actors.len() < deformers.len() {
            self.make_room(deformers.len());
        }
        for (k, d) in deformers.iter().enumerate() {
            let (at, radius) = match *d {
                Deformer::Sphere { center, radius } => (center, radius),
                Deformer::Box { center, half_extents, .. } => (center, half_extents.x.max(half_extents.z)),
                Deformer::Point { position, scale_per_m } => (position, 0.5 / scale_per_m.max(1e-3)),
                Deformer::Wheel { center, half_width, .. } => (center, half_width),
            };
            let ground = terrain.height_at(at.x, at.z);
            if d.lowest_point() >= ground + depth_m {
                continue;
            }
            let here = DVec2::new(f64::from(at.x), f64::from(at.z));
            if self.last[k].is_some_and(|p| p.distance(here) < f64::from(radius) * 0.5) {
                continue;
            }
            let yaw = self.last[k].map_or(0.0, |p| {
                let dir = here - p;
                dir.y.atan2(dir.x) as f32
            });
            self.last[k] = Some(here);
            let n = terrain.normal_at(at.x, at.z, 0.1);
            let rel = here - self.anchor;
            let ring = &mut self.actors[k];
            if ring.capacity() == 0 {
                // At its first contact an actor's ring gets its full size
                // (`kept` decals; the pages are touched only as it fills),
                // so rings never grow frame by frame: many actors moving
                // alike would otherwise all grow on the same frames.
                ring.reserve_exact(self.kept);
            }
            if ring.len() >= self.kept {
                ring.pop_front();
            }
            ring.push_back(Decal { place: [rel.x as f32, rel.y as f32, radius * 1.15, yaw], normal: [n.x, n.y, n.z, 1.0] });
            self.dirty = true;
        }
    }

    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    /// Decals held, all actors.
    #[must_use]
    pub fn len(&self) -> usize {
        self.actors.iter().map(VecDeque::len).sum()
    }

    /// Whether no decal is held.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every decal, oldest first per actor.
    pub fn iter(&self) -> impl Iterator<Item = &Decal> {
        self.actors.iter().flatten()
    }

    /// The anchor decal positions are relative to.
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    pub fn anchor(&self) -> DVec2 {
        self.anchor
    }
}

/// Draws the decal ring into the window's decal layer.
pub struct DecalPass {
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    instances: wgpu::Buffer,
    count: u32,
    /// The layer: window-local, [`DECAL_FORMAT`]; 1x1 and transparent until
    /// [`Self::allocate_layer`] (the decals technique's first frame).
    pub layer: wgpu::Texture,
    layer_view: wgpu::TextureView,
    /// Texels per side of the full layer.
    resolution: u32,
    /// The ring's decals as last uploaded, kept for its memory.
    upload: Vec<Decal>,
}

fn layer_texture(device: &wgpu::Device, side: u32) -> wgpu::Texture {
    // Zero-initialised by wgpu: transparent, no decal anywhere.
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("decal layer"),
        size: wgpu::Extent3d { width: side, height: side, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: DECAL_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

fn instance_buffer(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("decal instances"),
        size: bytes.max(256),
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The decal pipeline: instanced footprint quads blended over the layer.
fn decal_pipeline(device: &wgpu::Device, bgl: &wgpu::BindGroupLayout) -> wgpu::RenderPipeline {
    let pipeline_layout =
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("decal"), bind_group_layouts: &[Some(bgl)], immediate_size: 0 });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("decal"), source: wgpu::ShaderSource::Wgsl(shaders::DECAL.into()) });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("decal"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: 32,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4],
            })],
        },
        primitive: wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::TriangleStrip, cull_mode: None, ..Default::default() },
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: DECAL_FORMAT,
                blend: Some(wgpu::BlendState {
                    color: wgpu::BlendComponent::OVER,
                    alpha: wgpu::BlendComponent {
                        src_factor: wgpu::BlendFactor::One,
                        dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                        operation: wgpu::BlendOperation::Add,
                    },
                }),
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

impl DecalPass {
    /// Builds the pipeline, the footprint texture and the layer: `resolution`²
    /// when `full` (the decals technique is in use), else a transparent 1x1
    /// placeholder that renderers can bind, replaced by [`Self::allocate_layer`].
    #[must_use]
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, resolution: u32, full: bool) -> Self {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("decal"),
            entries: &[
                layout::uniform(0, wgpu::ShaderStages::VERTEX),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let pipeline = decal_pipeline(device, &bgl);
        use wgpu::util::DeviceExt as _;
        let footprint = device.create_texture_with_data(
            queue,
            &wgpu::TextureDescriptor {
                label: Some("decal footprint"),
                size: wgpu::Extent3d { width: FOOTPRINT_SIDE, height: FOOTPRINT_SIDE, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            bytemuck::cast_slice(&footprint_texture(FOOTPRINT_SIDE)),
        );
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("decal footprint"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let params = layout::uniform_buffer::<DecalParams>(device, "decal params");
        let bind_group = layout::bind_group(
            device,
            "decal",
            &bgl,
            &[
                params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&footprint.create_view(&wgpu::TextureViewDescriptor::default())),
                wgpu::BindingResource::Sampler(&sampler),
            ],
        );
        let layer = layer_texture(device, if full { resolution } else { 1 });
        let layer_view = layer.create_view(&wgpu::TextureViewDescriptor::default());
        Self { pipeline, params, bind_group, instances: instance_buffer(device, 32 * 1024), count: 0, layer, layer_view, resolution, upload: Vec::new() }
    }

    /// Replaces the 1x1 placeholder with the full `resolution`² layer; does
    /// nothing when it is already full. Renderers holding the old texture
    /// rebind ([`crate::snow::inspect::SnowInspect::decal_layer`] changes).
    pub fn allocate_layer(&mut self, device: &wgpu::Device) {
        if self.layer.width() != self.resolution {
            self.layer = layer_texture(device, self.resolution);
            self.layer_view = self.layer.create_view(&wgpu::TextureViewDescriptor::default());
        }
    }

    /// Bytes of GPU memory of the layer.
    #[must_use]
    pub fn layer_bytes(&self) -> u64 {
        u64::from(self.layer.width()) * u64::from(self.layer.height()) * 4
    }

    /// Records this frame's decals: uploads the ring when it changed and
    /// the window's placement (its corner and side), clears the layer and
    /// draws every decal into it (the presses' one form, as the capture's
    /// and the stamps').
    pub fn record(&mut self, cx: &mut FrameContext<'_>, ring: &mut DecalRing, (window_corner_m, extent_m): (DVec2, f32)) {
        self.upload(cx.device(), cx.queue(), ring, window_corner_m, extent_m);
        self.draw(cx);
    }

    /// Uploads the ring when it changed, and this frame's window placement.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, ring: &mut DecalRing, window_corner_m: DVec2, extent_m: f32) {
        let corner = window_corner_m - ring.anchor;
        let p = DecalParams { corner_m: [corner.x as f32, corner.y as f32], extent_m, _pad: 0.0 };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
        if ring.dirty {
            let decals = &mut self.upload;
            decals.clear();
            decals.extend(ring.iter().copied());
            let bytes: &[u8] = bytemuck::cast_slice(decals);
            if bytes.len() as u64 > self.instances.size() {
                self.instances = instance_buffer(device, (bytes.len() as u64).next_power_of_two());
            }
            queue.write_buffer(&self.instances, 0, bytes);
            self.count = decals.len() as u32;
            ring.dirty = false;
        }
    }

    /// Clears the layer and draws every uploaded decal into it.
    fn draw(&self, cx: &mut FrameContext<'_>) {
        let (encoder, timer) = (&mut *cx.encoder, &mut *cx.timer);
        let slot = timer.reserve("decals");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("decals"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.layer_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: timer.render_writes(slot),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if self.count > 0 {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_vertex_buffer(0, self.instances.slice(..));
            pass.draw(0..4, 0..self.count);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// `count` spheres pressing the snow (0.5 m deep on flat ground), each
    /// a radius further along x than at `step - 1`: a new contact each step.
    fn walkers(count: usize, step: usize) -> Vec<Deformer> {
        (0..count).map(|k| Deformer::Sphere { center: Vec3::new(step as f32 * 0.3, 0.3, k as f32), radius: 0.3 }).collect()
    }

    fn observe(ring: &mut DecalRing, count: usize, steps: std::ops::Range<usize>) {
        let terrain = TerrainSource::Flat { height_m: 0.0 };
        for step in steps {
            ring.observe(&walkers(count, step), &terrain, 0.5);
        }
    }

    #[test]
    fn a_few_actors_keep_their_last_contacts() {
        let mut ring = DecalRing::new(DEFAULT_PER_ACTOR, DVec2::ZERO);
        observe(&mut ring, 3, 0..1500);
        assert_eq!(ring.kept_per_actor(), DEFAULT_PER_ACTOR);
        assert_eq!(ring.len(), 3 * DEFAULT_PER_ACTOR);
        // The newest are kept: actor 0's last decal is at its last step.
        let last = ring.actors[0].back().expect("decals").place[0];
        assert!((last - 1499.0 * 0.3).abs() < 1e-2, "{last}");
    }

    #[test]
    fn a_crowd_shares_the_budget() {
        let mut ring = DecalRing::new(DEFAULT_PER_ACTOR, DVec2::ZERO);
        observe(&mut ring, 16, 0..1200);
        assert_eq!(ring.len(), 16 * DEFAULT_PER_ACTOR);
        // A crowd joins: the first sixteen give up their oldest contacts.
        observe(&mut ring, 16_384, 1200..1210);
        assert_eq!(ring.kept_per_actor(), DECAL_BUDGET / 16_384);
        assert!(ring.len() <= DECAL_BUDGET, "{} decals", ring.len());
        assert!(ring.actors.iter().all(|r| r.len() <= ring.kept_per_actor() && r.capacity() <= DEFAULT_PER_ACTOR));
        assert!(ring.actors[0].capacity() < DEFAULT_PER_ACTOR, "the early rings kept their memory");
        let last = ring.actors[0].back().expect("decals").place[0];
        assert!((last - 1209.0 * 0.3).abs() < 1e-2, "{last}");
    }
}
