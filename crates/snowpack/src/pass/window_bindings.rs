//! [`WindowBindings`]: the window's buffers as one bind group (group 1 of
//! every pass that reads or writes the window), made once per buffer set.
//!
//! | binding | resource | WGSL |
//! |---|---|---|
//! | 0 | `terrain_params` | `var<uniform> terrain_params: TerrainParams` |
//! | 1 | `heightmap` | `var<storage, read> heightmap: array<f32>` |
//! | 2 | `snow` | `var<storage, A> snow: array<u32>` (or `atomic<u32>`) |
//! | 3 | `stamps` | `var<storage, A> stamps: array<u32>` (or `atomic<u32>`) |
//! | 4 | `fallen` | `var<storage, A> fallen: array<f32>` |
//!
//! The changed-tile flags stay in the two passes that write them: with
//! them, a pass of its own four buffers (the snow coat) would bind nine
//! storage buffers, over the eight a WebGPU device (or a game's default
//! limits) allows a stage.
//!
//! `A` is `read` in a pass of [`WindowAccess::Read`] and `read_write` in
//! one of [`WindowAccess::Write`]: two layouts and two groups over the same
//! buffers, so a pass that only reads keeps read-only storage (which a
//! driver may cache) and no pass binds a buffer twice. A shader declares
//! the bindings it uses, at these numbers and with its access; a test
//! (`tests/uniforms.rs`) checks every shader's group 1 against this table.
//! When a buffer is replaced (the footprints or the changed-tile flags
//! allocated), the groups are made again and every pass sees the new ones
//! at its next record: nothing else binds the window.

use crate::gpu::layout;

/// `origin` (a window's global texel of local (0, 0), `[column, row]`)
/// wrapped into `0..res`: where local (0, 0) lies in the toroidal storage.
/// The per-texel passes take it (`storage_index_wrapped` in
/// `shared/window.wgsl`) so that no texel divides; their `record` fills it.
#[must_use]
pub fn storage_origin(origin: [i32; 2], res: u32) -> [u32; 2] {
    let r = i64::from(res.max(1));
    [i64::from(origin[0]).rem_euclid(r) as u32, i64::from(origin[1]).rem_euclid(r) as u32]
}

/// How a pass uses the window's snow, footprints and snowfall.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindowAccess {
    /// Reads them (`var<storage, read>`).
    Read,
    /// Writes some of them (`var<storage, read_write>`, all three).
    Write,
}

/// The window's bindings: see the module documentation.
pub struct WindowBindings {
    read_layout: wgpu::BindGroupLayout,
    write_layout: wgpu::BindGroupLayout,
    read: wgpu::BindGroup,
    write: wgpu::BindGroup,
}

/// The window's buffers, in binding order.
pub struct WindowBuffers<'a> {
    /// `TerrainParams` uniform.
    pub terrain_params: &'a wgpu::Buffer,
    /// Heightmap samples.
    pub heightmap: &'a wgpu::Buffer,
    /// Snow words.
    pub snow: &'a wgpu::Buffer,
    /// Footprints.
    pub stamps: &'a wgpu::Buffer,
    /// Snowfall above the rest depth.
    pub fallen: &'a wgpu::Buffer,
}

/// The layout entries of group 1 for `access` (the table above).
#[must_use]
pub fn window_layout_entries(access: WindowAccess) -> [wgpu::BindGroupLayoutEntry; 5] {
    let read_only = access == WindowAccess::Read;
    [
        layout::uniform(0, wgpu::ShaderStages::COMPUTE),
        layout::storage(1, true),
        layout::storage(2, read_only),
        layout::storage(3, read_only),
        layout::storage(4, read_only),
    ]
}

impl WindowBindings {
    /// Both layouts, and both groups over `buffers`.
    #[must_use]
    pub fn new(device: &wgpu::Device, buffers: &WindowBuffers<'_>) -> Self {
        let make = |label: &str, access| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &window_layout_entries(access) })
        };
        let read_layout = make("window (read)", WindowAccess::Read);
        let write_layout = make("window (write)", WindowAccess::Write);
        let (read, write) = (Self::make_group(device, &read_layout, buffers), Self::make_group(device, &write_layout, buffers));
        Self { read_layout, write_layout, read, write }
    }

    fn make_group(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, b: &WindowBuffers<'_>) -> wgpu::BindGroup {
        layout::bind_group(
            device,
            "window",
            layout,
            &[
                b.terrain_params.as_entire_binding(),
                b.heightmap.as_entire_binding(),
                b.snow.as_entire_binding(),
                b.stamps.as_entire_binding(),
                b.fallen.as_entire_binding(),
            ],
        )
    }

    /// Makes both groups again over `buffers` (one was replaced); the layouts stay.
    pub fn rebind(&mut self, device: &wgpu::Device, buffers: &WindowBuffers<'_>) {
        self.read = Self::make_group(device, &self.read_layout, buffers);
        self.write = Self::make_group(device, &self.write_layout, buffers);
    }

    /// Group 1's layout for a pass of `access`.
    #[must_use]
    pub fn layout(&self, access: WindowAccess) -> &wgpu::BindGroupLayout {
        match access {
            WindowAccess::Read => &self.read_layout,
            WindowAccess::Write => &self.write_layout,
        }
    }

    /// Group 1 for a pass of `access`.
    #[must_use]
    pub fn group(&self, access: WindowAccess) -> &wgpu::BindGroup {
        match access {
            WindowAccess::Read => &self.read,
            WindowAccess::Write => &self.write,
        }
    }
}
