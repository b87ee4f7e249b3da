//! The GPU side of the resident tiles: the slots' buffer and the passes
//! bound to it (exchange, restore, seal, weather), and the recordings that
//! need nothing but them: a ledger sweep and the weather outside the window.

use super::layout::SlotLayout;
use crate::deform::resources::DeformResources;
use crate::frame::{FrameContext, WindowFrame};
use crate::gpu::{GpuContext, GpuTimer};
use crate::persist::TileKey;
use crate::tiles::exchange::{ExchangeParams, ExchangePass};
use crate::tiles::restore::TileRestorePass;
use crate::tiles::seal::TileSealPass;
use crate::tiles::slots::SlotTable;
use crate::tiles::weather::{TileWeatherPass, WeatherParams};

/// The resident tiles' buffer and the passes bound to it.
pub(super) struct TilePasses {
    /// Every slot's planes.
    pub(super) tiles: wgpu::Buffer,
    pub(super) exchange: ExchangePass,
    pub(super) restore: TileRestorePass,
    pub(super) seal: TileSealPass,
    weather: TileWeatherPass,
    /// The weather pass's slot list, rebuilt each frame in place.
    weather_slots: Vec<u32>,
}

impl TilePasses {
    /// The passes over `tiles` (the slots of `slots`) for the window of `res`.
    pub(super) fn new(device: &wgpu::Device, res: &DeformResources, tiles: wgpu::Buffer, slots: &SlotTable) -> Self {
        Self {
            exchange: ExchangePass::new(device, res, &tiles, slots.table_buffer()),
            restore: TileRestorePass::new(device, res, &tiles),
            seal: TileSealPass::new(device, res, &tiles),
            weather: TileWeatherPass::new(device, res, slots.owners_buffer(), &tiles),
            tiles,
            weather_slots: Vec::new(),
        }
    }

    /// Binds the passes to a new `tiles` buffer (and to `res`), keeping the
    /// weather's slot list.
    pub(super) fn rebind(&mut self, device: &wgpu::Device, res: &DeformResources, tiles: wgpu::Buffer, slots: &SlotTable) {
        let weather_slots = std::mem::take(&mut self.weather_slots);
        *self = Self { weather_slots, ..Self::new(device, res, tiles, slots) };
    }

    /// GPU memory of the slots and the passes' own buffers (bytes).
    pub(super) fn gpu_bytes(&self) -> u64 {
        self.tiles.size() + self.weather.memory_bytes() + self.seal.memory_bytes() + self.restore.memory_bytes()
    }

    /// Counts the whole window at `at` in the mass ledger, as left (`kind`
    /// [`ExchangeParams::STASH`]) or entered (0), in a submission of its own
    /// (the sweep's uniform is its own).
    pub(super) fn record_sweep(&self, ctx: &GpuContext, res: &DeformResources, layout: &SlotLayout, at: [i64; 2], kind: u32) {
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ledger sweep") });
        let params = layout.exchange_params(res, at, at, ExchangeParams::SWEEP | ExchangeParams::COUNT | kind);
        self.exchange.record(&mut FrameContext::new(ctx, &mut encoder, &mut GpuTimer::disabled()), res, params, &[[0, 0, res.resolution, res.resolution]]);
        ctx.queue.submit([encoder.finish()]);
    }

    /// Records this frame's weather on the resident tiles outside the window
    /// at `origin`: `refill_m`, `fall_m` and `quanta` are this frame's.
    pub(super) fn record_weather(
        &mut self,
        cx: &mut FrameContext<'_>,
        (res, layout, slots): (&DeformResources, &SlotLayout, &SlotTable),
        frame @ &WindowFrame { origin, .. }: &WindowFrame,
        (refill_m, fall_m): (f32, f32),
        quanta: u32,
    ) {
        // Only tiles reaching outside the window: the update has the rest.
        let (side, n) = (i64::from(layout.grid.side()), i64::from(layout.grid.resolution()));
        let inside =
            |k: TileKey| k.col * side >= origin[0] && (k.col + 1) * side <= origin[0] + n && k.row * side >= origin[1] && (k.row + 1) * side <= origin[1] + n;
        self.weather_slots.clear();
        self.weather_slots.extend(slots.owned().filter(|&(_, k)| !inside(k)).map(|(s, _)| s as u32));
        self.weather.record(
            cx,
            res,
            &WeatherParams {
                origin: [origin[0] as i32, origin[1] as i32],
                resolution: layout.grid.resolution(),
                side: layout.grid.side(),
                texel_m: frame.texel_m,
                flags: if frame.use_fallen { WeatherParams::USE_FALLEN } else { 0 },
                planes: layout.planes() as u32,
                depth_m: frame.depth_m,
                refill_m,
                fall_m,
                max_fallen_m: frame.max_fallen_m,
                quanta,
                low_m: frame.low_m,
                high_m: frame.high_m,
                count: 0,
                _pad: 0,
            },
            &self.weather_slots,
        );
    }
}
