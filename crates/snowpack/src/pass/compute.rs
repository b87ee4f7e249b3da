//! [`ComputePass`]: the one shape of a compute pass. A WGSL file with entry
//! point `main`; its uniform `P` at binding 0 of group 0; the pass's own
//! buffers and textures at bindings 1.. of group 0 ([`Slot`]); the window's
//! buffers, when it reads or writes the window, as group 1
//! ([`WindowBindings`], shared by every such pass);
//! and pipelines specialised on one `u32` override constant, built on first
//! use of each value. A pass records with one call, [`ComputePass::record`].
//!
//! Why specialise: a pass whose uniforms choose among branches (which
//! inputs a frame has, which rim formula) runs fastest when the driver sees
//! the choice as a constant and drops the branches not taken. On GPUs a
//! uniform branch is cheap either way; SIMD software adapters (llvmpipe,
//! SwiftShader: CI, and browsers without a GPU) run every side of a uniform
//! `if` for every invocation, and lavapipe also recompiles a pipeline on
//! each bind while uniforms decide its branches. The shader declares
//! `override NAME: u32 = 0xffffffffu;` and reads the uniform only while the
//! constant keeps that default, so a pipeline built without it still works.

use std::cell::Cell;
use std::sync::{Arc, Mutex};

use super::window_bindings::{WindowAccess, WindowBindings};
use crate::frame::FrameContext;
use crate::gpu::layout;

/// What a pass binds in group 0 after its uniform, in binding order from 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// A uniform buffer.
    Uniform,
    /// A storage buffer the shader only reads (`var<storage, read>`).
    Read,
    /// A storage buffer the shader writes (`var<storage, read_write>`).
    ReadWrite,
    /// A depth texture read with `textureLoad` ([`layout::depth_texture`]).
    Depth,
    /// A `u32` texture read with `textureLoad` (`texture_2d<u32>`).
    UintTexture,
}

impl Slot {
    fn entry(self, binding: u32) -> wgpu::BindGroupLayoutEntry {
        match self {
            Self::Uniform => layout::uniform(binding, wgpu::ShaderStages::COMPUTE),
            Self::Read => layout::storage(binding, true),
            Self::ReadWrite => layout::storage(binding, false),
            Self::Depth => layout::depth_texture(binding),
            Self::UintTexture => wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Uint,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
        }
    }
}

/// How a [`ComputePass`] is built.
#[derive(Clone, Copy, Debug)]
pub struct PassShape<'a> {
    /// Name in labels and GPU timings.
    pub label: &'static str,
    /// The composed WGSL (`low_level::shaders`).
    pub source: &'a str,
    /// Group 0's bindings after the uniform.
    pub slots: &'a [Slot],
    /// The override constant the pipelines are specialised on (`None`: one
    /// pipeline, the `variant` given to `record` is ignored).
    pub specialise_on: Option<&'static str>,
    /// Other override constants, the same for every pipeline (the terrain's kind).
    pub constants: &'a [(&'static str, f64)],
    /// Whether group 1 is the window's buffers, and how the shader uses them.
    pub window: Option<WindowAccess>,
}

/// The pipelines of one shader, one per value of its specialisation
/// constant; shared by a pass and its [`ComputePass::sibling`]s.
struct Pipelines {
    device: wgpu::Device,
    label: &'static str,
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    constant: Option<&'static str>,
    fixed: Vec<(&'static str, f64)>,
    /// Pipelines built so far, by value (a pass uses a handful).
    built: Mutex<Vec<(u32, wgpu::ComputePipeline)>>,
}

impl Pipelines {
    /// The pipeline for `value`, built now on its first use.
    fn get(&self, value: u32) -> wgpu::ComputePipeline {
        let value = if self.constant.is_some() { value } else { 0 };
        // A poisoned lock only means another thread panicked while building;
        // the list itself is always whole.
        let mut built = self.built.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, pipeline)) = built.iter().find(|(v, _)| *v == value) {
            return pipeline.clone();
        }
        let mut constants = self.fixed.clone();
        if let Some(name) = self.constant {
            constants.push((name, f64::from(value)));
        }
        let pipeline = self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(self.label),
            layout: Some(&self.layout),
            module: &self.module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
            cache: None,
        });
        built.push((value, pipeline.clone()));
        pipeline
    }
}

/// One compute pass: see the module documentation.
pub struct ComputePass<P> {
    pipelines: Arc<Pipelines>,
    /// Group 0's layout.
    layout: wgpu::BindGroupLayout,
    window: Option<WindowAccess>,
    params: wgpu::Buffer,
    /// The uniforms last written, so an unchanged frame writes none.
    written: Cell<Option<P>>,
    /// Group 0: the uniform and the pass's own resources ([`Self::bind`]).
    group: Option<wgpu::BindGroup>,
}

impl<P: bytemuck::Pod> ComputePass<P> {
    /// Compiles `shape.source` and lays out its groups; builds no pipeline
    /// yet. `window` is the window's bindings when `shape.window` is set
    /// (their layouts). A pass whose slots are all its own is bound by
    /// [`Self::bind`] before its first record.
    #[must_use]
    pub fn new(device: &wgpu::Device, shape: &PassShape<'_>, window: Option<&WindowBindings>) -> Self {
        let label = shape.label;
        let mut entries = vec![Slot::Uniform.entry(0)];
        entries.extend(shape.slots.iter().zip(1..).map(|(slot, binding)| slot.entry(binding)));
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries });
        let window_layout = shape.window.zip(window).map(|(access, w)| w.layout(access));
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(shape.source.into()) });
        let groups: Vec<Option<&wgpu::BindGroupLayout>> = std::iter::once(Some(&layout)).chain(window_layout.map(Some)).collect();
        let pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some(label), bind_group_layouts: &groups, immediate_size: 0 });
        let pipelines = Pipelines {
            device: device.clone(),
            label,
            module,
            layout: pipeline_layout,
            constant: shape.specialise_on,
            fixed: shape.constants.to_vec(),
            built: Mutex::new(Vec::new()),
        };
        let params = layout::uniform_buffer::<P>(device, label);
        Self { pipelines: Arc::new(pipelines), layout, window: shape.window, params, written: Cell::new(None), group: None }
    }

    /// Another pass of the same shader and pipelines with a uniform of its
    /// own, for a second record in one submission (the exchange's stash and
    /// load): uniforms are written before the submission runs, so two
    /// records of one pass in it would both see the last.
    #[must_use]
    pub fn sibling(&self, device: &wgpu::Device) -> Self {
        let params = layout::uniform_buffer::<P>(device, self.pipelines.label);
        Self { pipelines: Arc::clone(&self.pipelines), layout: self.layout.clone(), window: self.window, params, written: Cell::new(None), group: None }
    }

    /// Binds the pass's own resources, one per [`Slot`] in order (after the
    /// uniform); again whenever one of them is replaced (a buffer grown).
    pub fn bind(&mut self, device: &wgpu::Device, resources: &[wgpu::BindingResource<'_>]) {
        self.group = Some(self.make_group(device, resources));
    }

    /// A group 0 of this pass's uniform and `resources`, not kept: for a pass
    /// whose own resources change from record to record (each character's
    /// buffers), given to [`Self::record_with`].
    #[must_use]
    pub fn make_group(&self, device: &wgpu::Device, resources: &[wgpu::BindingResource<'_>]) -> wgpu::BindGroup {
        let mut all = vec![self.params.as_entire_binding()];
        all.extend(resources.iter().cloned());
        layout::bind_group(device, self.pipelines.label, &self.layout, &all)
    }

    /// Records one timed dispatch of `groups` workgroups with `params` (its
    /// uniform written only when it changed), the pipeline of `variant`, and
    /// the window's bindings `window` for a pass that uses them.
    ///
    /// A pass not yet bound, or one of the window recorded without its
    /// bindings, records nothing and logs the mistake (no wgpu validation
    /// panic in a game's frame).
    pub fn record(&self, cx: &mut FrameContext<'_>, window: Option<&WindowBindings>, params: &P, variant: u32, groups: (u32, u32)) {
        self.record_labelled(cx, self.pipelines.label, window, params, variant, groups);
    }

    /// [`Self::record`] timed under another name (a pass with two roles).
    pub fn record_labelled(
        &self,
        cx: &mut FrameContext<'_>,
        label: &'static str,
        window: Option<&WindowBindings>,
        params: &P,
        variant: u32,
        groups: (u32, u32),
    ) {
        let Some(group) = &self.group else {
            tracing::error!(pass = label, "a compute pass recorded before it was bound: skipped");
            return;
        };
        self.dispatch(cx, label, group, window, params, variant, groups);
    }

    /// [`Self::record`] with a group 0 from [`Self::make_group`].
    pub fn record_with(
        &self,
        cx: &mut FrameContext<'_>,
        group: &wgpu::BindGroup,
        window: Option<&WindowBindings>,
        params: &P,
        variant: u32,
        groups: (u32, u32),
    ) {
        self.dispatch(cx, self.pipelines.label, group, window, params, variant, groups);
    }

    #[expect(clippy::too_many_arguments, reason = "the three public records' common body: each argument is one of theirs")]
    fn dispatch(
        &self,
        cx: &mut FrameContext<'_>,
        label: &'static str,
        group: &wgpu::BindGroup,
        window: Option<&WindowBindings>,
        params: &P,
        variant: u32,
        groups: (u32, u32),
    ) {
        let window_group = match (self.window, window) {
            (Some(access), Some(w)) => Some(w.group(access)),
            (None, _) => None,
            (Some(_), None) => {
                tracing::error!(pass = label, "a window pass recorded without the window's bindings: skipped");
                return;
            }
        };
        // Compared as bytes: the uniforms are plain data.
        if self.written.get().is_none_or(|w| bytemuck::bytes_of(&w) != bytemuck::bytes_of(params)) {
            cx.queue().write_buffer(&self.params, 0, bytemuck::bytes_of(params));
            self.written.set(Some(*params));
        }
        let pipeline = self.pipelines.get(variant);
        let slot = cx.timer.reserve(label);
        let mut pass = cx.encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: cx.timer.compute_writes(slot) });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, group, &[]);
        if let Some(w) = window_group {
            pass.set_bind_group(1, w, &[]);
        }
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }
}
