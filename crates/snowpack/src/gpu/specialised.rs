//! Compute pipelines specialised on a `u32` pipeline-overridable constant,
//! built on first use of each value.
//!
//! A pass whose uniforms choose among branches (which inputs a frame has,
//! which rim formula) runs fastest when the driver sees the choice as a
//! constant and drops the branches not taken. On GPUs a uniform branch is
//! cheap either way; SIMD software adapters (llvmpipe, SwiftShader: CI, and
//! browsers without a GPU) run every side of a uniform `if` for every
//! invocation, and lavapipe also recompiles a pipeline on each bind while
//! uniforms decide its branches. The shader declares
//! `override NAME: u32 = 0xffffffffu;` and reads the uniform only while the
//! constant keeps that default, so a pipeline built without it still works.

use std::sync::Mutex;

/// One compute pipeline (entry point `main`, one bind group) per value of a
/// `u32` override constant.
pub struct SpecialisedPipeline {
    device: wgpu::Device,
    label: &'static str,
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    /// Name of the constant each pipeline is specialised on.
    constant: &'static str,
    /// Other override constants, the same for every pipeline.
    fixed: Vec<(&'static str, f64)>,
    /// Pipelines built so far, by value (a pass uses a handful).
    built: Mutex<Vec<(u32, wgpu::ComputePipeline)>>,
}

impl SpecialisedPipeline {
    /// Compiles `source` and lays out its bind group from `entries`; builds
    /// no pipeline yet. Returns the bind group layout too.
    #[must_use]
    pub fn new(
        device: &wgpu::Device,
        label: &'static str,
        source: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
        constant: &'static str,
        fixed: &[(&'static str, f64)],
    ) -> (Self, wgpu::BindGroupLayout) {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) });
        let layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some(label), bind_group_layouts: &[Some(&bgl)], immediate_size: 0 });
        let pass = Self { device: device.clone(), label, module, layout, constant, fixed: fixed.to_vec(), built: Mutex::new(Vec::new()) };
        (pass, bgl)
    }

    /// The pipeline with the constant set to `value`, built now if it is the
    /// first use of that value.
    #[must_use]
    pub fn get(&self, value: u32) -> wgpu::ComputePipeline {
        // A poisoned lock only means another thread panicked while building;
        // the list itself is always whole.
        let mut built = self.built.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, pipeline)) = built.iter().find(|(v, _)| *v == value) {
            return pipeline.clone();
        }
        let mut constants = self.fixed.clone();
        constants.push((self.constant, f64::from(value)));
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
