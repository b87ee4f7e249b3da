//! A ring of staging buffers that brings GPU data back a few frames late
//! without ever stalling: a frame whose slots are all in flight skips its copy.
//!
//! Every readback here is mapped by wgpu when the encoder holding its copy is
//! submitted (`CommandEncoder::map_buffer_on_submit`), so nothing needs
//! calling after a submit; what has arrived is taken at the next frame,
//! after a non-blocking `device.poll`.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use crate::gpu::context::GpuContextExt;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

const MAPPING: u8 = 0;
const MAPPED: u8 = 1;
const FAILED: u8 = 2;

/// Where a mapping requested with [`MapFlag::on_submit`] stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapState {
    /// Not back yet: the encoder is not submitted, or the GPU is not done,
    /// or no poll has run the callback yet.
    Pending,
    /// Mapped: the bytes can be read.
    Mapped,
    /// The mapping failed, or the encoder was dropped without being submitted.
    Failed,
}

/// The state of one mapping started when its encoder is submitted.
#[derive(Clone, Debug)]
pub struct MapFlag(Arc<AtomicU8>);

/// Held by wgpu's mapping callback: dropped without the callback running
/// (the encoder never submitted), it marks the mapping failed.
struct MapGuard(Arc<AtomicU8>);

impl Drop for MapGuard {
    fn drop(&mut self) {
        let _ = self.0.compare_exchange(MAPPING, FAILED, Ordering::AcqRel, Ordering::Acquire);
    }
}

impl MapFlag {
    /// Asks wgpu to map `buffer[..len]` for reading when `encoder` is
    /// submitted (after the copies recorded into it so far), and returns
    /// the flag its callback sets.
    pub fn on_submit(encoder: &wgpu::CommandEncoder, buffer: &wgpu::Buffer, len: u64) -> Self {
        let flag = Arc::new(AtomicU8::new(MAPPING));
        let guard = MapGuard(Arc::clone(&flag));
        encoder.map_buffer_on_submit(buffer, wgpu::MapMode::Read, ..len, move |result| {
            guard.0.store(if result.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
        });
        Self(flag)
    }

    /// A flag that has already arrived (nothing to map).
    #[must_use]
    pub fn arrived() -> Self {
        Self(Arc::new(AtomicU8::new(MAPPED)))
    }

    /// Where the mapping stands (callbacks run inside `device.poll` or a submit).
    #[must_use]
    pub fn state(&self) -> MapState {
        match self.0.load(Ordering::Acquire) {
            MAPPING => MapState::Pending,
            MAPPED => MapState::Mapped,
            _ => MapState::Failed,
        }
    }
}

enum SlotState<M> {
    Free,
    /// Copy recorded, mapped when its encoder is submitted; the flag turns
    /// mapped or failed in wgpu's callback.
    Mapping {
        meta: M,
        seq: u64,
        len: u64,
        flag: MapFlag,
    },
}

struct Slot<M> {
    buffer: wgpu::Buffer,
    state: SlotState<M>,
}

/// Staging buffers of one size, each carrying metadata `M` (for example the
/// window origin the copied data belongs to).
pub struct ReadbackRing<M> {
    slots: Vec<Slot<M>>,
    size: u64,
    next_seq: u64,
    delivered_seq: Option<u64>,
    skipped: u64,
}

impl<M> ReadbackRing<M> {
    /// `count` staging buffers of `size` bytes.
    #[must_use]
    pub fn new(device: &wgpu::Device, label: &str, size: u64, count: usize) -> Self {
        let slots = (0..count)
            .map(|k| Slot {
                buffer: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&format!("{label} readback {k}")),
                    size,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
                state: SlotState::Free,
            })
            .collect();
        Self { slots, size, next_seq: 0, delivered_seq: None, skipped: 0 }
    }

    /// Size of each staging buffer in bytes.
    #[must_use]
    pub fn size(&self) -> u64 {
        self.size
    }

    /// Bytes of GPU memory the ring holds.
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.size * self.slots.len() as u64
    }

    /// Records a copy of `size` bytes of `src` into a free slot, mapped for
    /// reading when `encoder` is submitted; returns false (and records
    /// nothing, counted in [`Self::skipped`]) when every slot is still in
    /// flight.
    pub fn record_copy(&mut self, encoder: &mut wgpu::CommandEncoder, src: &wgpu::Buffer, meta: M) -> bool {
        self.record_copy_len(encoder, src, self.size, meta)
    }

    /// Like [`Self::record_copy`] for the first `len` bytes of `src` (at most
    /// the slot size, a multiple of 4); only those come back.
    pub fn record_copy_len(&mut self, encoder: &mut wgpu::CommandEncoder, src: &wgpu::Buffer, len: u64, meta: M) -> bool {
        let len = len.min(self.size);
        let Some(slot) = self.slots.iter_mut().find(|s| matches!(s.state, SlotState::Free)) else {
            self.skipped += 1;
            return false;
        };
        let flag = if len > 0 {
            encoder.copy_buffer_to_buffer(src, 0, &slot.buffer, 0, len);
            MapFlag::on_submit(encoder, &slot.buffer, len)
        } else {
            // Nothing to map (an empty answer): it has arrived.
            MapFlag::arrived()
        };
        slot.state = SlotState::Mapping { meta, seq: self.next_seq, len, flag };
        self.next_seq += 1;
        true
    }

    /// Copies not recorded so far because every slot was in flight (the
    /// data was behind, or the caller has not taken what arrived).
    #[must_use]
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// Whether [`Self::record_copy_len`] would find a free slot now (so a
    /// caller can skip the work whose result it would copy).
    #[must_use]
    pub fn has_free_slot(&self) -> bool {
        self.slots.iter().any(|s| matches!(s.state, SlotState::Free))
    }

    /// Whether a mapping has been asked for and its callback has not run yet.
    /// Once the GPU is idle this is only the time until some thread's poll
    /// fires the callback (wgpu fires them from whichever poll collected them).
    #[must_use]
    pub fn callbacks_pending(&self) -> bool {
        self.slots.iter().any(|s| matches!(&s.state, SlotState::Mapping { flag, .. } if flag.state() == MapState::Pending))
    }

    /// Whether any slot is waiting for the GPU.
    #[must_use]
    pub fn in_flight(&self) -> bool {
        self.slots.iter().any(|s| !matches!(s.state, SlotState::Free))
    }

    /// Returns the newest data that has arrived (older arrivals are dropped),
    /// without waiting; call `device.poll(PollType::Poll)` before it.
    pub fn take_latest(&mut self) -> Option<(M, Vec<u8>)> {
        let mut best: Option<(usize, u64)> = None;
        for (k, slot) in self.slots.iter_mut().enumerate() {
            let SlotState::Mapping { seq, flag, .. } = &slot.state else { continue };
            match flag.state() {
                MapState::Mapped if best.is_none_or(|(_, s)| *seq > s) => {
                    best = Some((k, *seq));
                }
                MapState::Failed => slot.state = SlotState::Free,
                _ => {}
            }
        }
        let (index, seq) = best?;
        // Free every arrived slot; deliver only the newest, and only if it is
        // newer than what was delivered before.
        let mut result = None;
        for (k, slot) in self.slots.iter_mut().enumerate() {
            let arrived = matches!(&slot.state, SlotState::Mapping { flag, .. } if flag.state() == MapState::Mapped);
            if !arrived {
                continue;
            }
            let SlotState::Mapping { meta, len, .. } = std::mem::replace(&mut slot.state, SlotState::Free) else {
                continue;
            };
            if k == index && self.delivered_seq.is_none_or(|d| seq > d) {
                // An empty copy was never mapped: it arrives as no bytes.
                let bytes = if len == 0 { Ok(Vec::new()) } else { slot.buffer.slice(..len).get_mapped_range().map(|view| view.to_vec()) };
                if let Ok(bytes) = bytes {
                    result = Some((meta, bytes));
                }
            }
            if len > 0 {
                slot.buffer.unmap();
            }
        }
        if result.is_some() {
            self.delivered_seq = Some(seq);
        }
        result
    }
    /// Returns every copy that has arrived, oldest first, without waiting
    /// (for data where each copy counts, such as flags cleared after each
    /// copy, unlike [`Self::take_latest`] which keeps only the newest); call
    /// `device.poll(PollType::Poll)` before it. Copies that failed to map
    /// are dropped.
    pub fn take_arrived(&mut self) -> Vec<(M, Vec<u8>)> {
        let mut arrived = Vec::new();
        for slot in &mut self.slots {
            let state = match &slot.state {
                SlotState::Mapping { flag, .. } => flag.state(),
                SlotState::Free => continue,
            };
            if state == MapState::Pending {
                continue;
            }
            let SlotState::Mapping { meta, seq, len, .. } = std::mem::replace(&mut slot.state, SlotState::Free) else {
                continue;
            };
            if state == MapState::Mapped {
                let bytes = if len == 0 { Ok(Vec::new()) } else { slot.buffer.slice(..len).get_mapped_range().map(|view| view.to_vec()) };
                if len > 0 {
                    slot.buffer.unmap();
                }
                if let Ok(bytes) = bytes {
                    arrived.push((seq, meta, bytes));
                }
            }
        }
        arrived.sort_by_key(|(seq, _, _)| *seq);
        if let Some((seq, _, _)) = arrived.last() {
            self.delivered_seq = Some(self.delivered_seq.map_or(*seq, |d| d.max(*seq)));
        }
        arrived.into_iter().map(|(_, meta, bytes)| (meta, bytes)).collect()
    }
}

/// Copies a whole buffer into a staging buffer and waits for it (blocking).
pub fn read_buffer(ctx: &crate::GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>, crate::error::SnowError> {
    ctx.guarded(|| map_blocking(ctx, &copy_to_staging(ctx, buffer)))
}

/// [`read_buffer`] without blocking (see `MappedRead`).
pub fn read_buffer_async(ctx: &crate::GpuContext, buffer: &wgpu::Buffer) -> MappedRead {
    MappedRead::new(&ctx.device, copy_to_staging(ctx, buffer))
}

/// A `MAP_READ` copy of all of `buffer`, submitted.
fn copy_to_staging(ctx: &crate::GpuContext, buffer: &wgpu::Buffer) -> wgpu::Buffer {
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback staging"),
        size: buffer.size(),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
    ctx.queue.submit([encoder.finish()]);
    staging
}

/// Maps a `MAP_READ` buffer whose copy has been submitted, waits for it and
/// returns its bytes (blocking; for tests, headless frames and tools).
pub fn map_blocking(ctx: &crate::GpuContext, staging: &wgpu::Buffer) -> Result<Vec<u8>, crate::error::SnowError> {
    use crate::error::SnowError;
    let (tx, rx) = std::sync::mpsc::channel();
    staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.wait_idle("reading back a buffer")?;
    rx.recv_timeout(std::time::Duration::from_secs(5))
        .map_err(|_| SnowError::Readback("the map callback never ran".to_owned()))?
        .map_err(|e| SnowError::Readback(e.to_string()))?;
    let bytes = staging.slice(..).get_mapped_range().map_err(|e| SnowError::Readback(e.to_string()))?.to_vec();
    staging.unmap();
    Ok(bytes)
}

/// The bytes of a `MAP_READ` buffer whose copy has been submitted, as a
/// future that never blocks: the browser build's readbacks (where
/// `device.poll` cannot wait) and any async caller's.
///
/// On the web the browser runs the mapping callback, which wakes the task.
/// Natively callbacks run inside `device.poll`, so each poll of the future
/// makes one non-blocking `device.poll` and, while the copy is not back, asks
/// to be polled again (an executor's next turn) rather than parking the thread.
pub struct MappedRead {
    buffer: wgpu::Buffer,
    device: wgpu::Device,
    shared: std::sync::Arc<std::sync::Mutex<MapShared>>,
}

#[derive(Default)]
struct MapShared {
    result: Option<Result<(), wgpu::BufferAsyncError>>,
    waker: Option<std::task::Waker>,
}

impl MappedRead {
    /// Starts mapping all of `buffer` (`MAP_READ`, its copy submitted).
    #[must_use]
    pub fn new(device: &wgpu::Device, buffer: wgpu::Buffer) -> Self {
        let shared = std::sync::Arc::new(std::sync::Mutex::new(MapShared::default()));
        let done = std::sync::Arc::clone(&shared);
        buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            if let Ok(mut s) = done.lock() {
                s.result = Some(r);
                if let Some(w) = s.waker.take() {
                    w.wake();
                }
            }
        });
        Self { buffer, device: device.clone(), shared }
    }
}

impl std::future::Future for MappedRead {
    type Output = Result<Vec<u8>, crate::error::SnowError>;

    fn poll(self: std::pin::Pin<&mut Self>, cx: &mut std::task::Context<'_>) -> std::task::Poll<Self::Output> {
        use crate::error::SnowError;
        if !cfg!(target_arch = "wasm32") {
            self.device.poll(wgpu::PollType::Poll).map_err(|e| SnowError::Readback(format!("polling the GPU: {e}")))?;
        }
        let mut shared = self.shared.lock().map_err(|_| SnowError::Readback("a readback's state was poisoned".to_owned()))?;
        match shared.result.take() {
            Some(Ok(())) => {
                drop(shared);
                let bytes = self.buffer.slice(..).get_mapped_range().map_err(|e| SnowError::Readback(e.to_string()))?.to_vec();
                self.buffer.unmap();
                std::task::Poll::Ready(Ok(bytes))
            }
            Some(Err(e)) => std::task::Poll::Ready(Err(SnowError::Readback(e.to_string()))),
            None => {
                shared.waker = Some(cx.waker().clone());
                if !cfg!(target_arch = "wasm32") {
                    // Natively only a later `device.poll` runs the callback: come back next turn.
                    cx.waker().wake_by_ref();
                }
                std::task::Poll::Pending
            }
        }
    }
}

/// A copy of a 4-byte-per-texel 2D texture (a frame, a screenshot) into CPU
/// memory: [`Self::record`] into an encoder, submit, then [`Self::read`]
/// (blocking) or [`Self::read_async`].
pub struct TextureReadback {
    staging: wgpu::Buffer,
    size: (u32, u32),
    padded_row: u32,
}

impl TextureReadback {
    /// Records a copy of mip 0 of `texture` (which needs `COPY_SRC`).
    pub fn record(device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, texture: &wgpu::Texture) -> Self {
        let size = (texture.width(), texture.height());
        let padded_row = (size.0 * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("texture readback"),
            size: u64::from(padded_row) * u64::from(size.1),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded_row), rows_per_image: None },
            },
            wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
        );
        Self { staging, size, padded_row }
    }

    /// Width and height of the copied texture.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// Waits for the copy (submitted by the caller) and returns the texels row
    /// by row without padding, 4 bytes each, in the texture's own channel order.
    pub fn read(&self, ctx: &crate::GpuContext) -> Result<Vec<u8>, crate::error::SnowError> {
        let bytes = ctx.guarded(|| map_blocking(ctx, &self.staging))?;
        Ok(self.unpad(&bytes))
    }

    /// [`Self::read`] without blocking: the texels once the copy is back
    /// (see `MappedRead`); what the browser build reads its frames with.
    pub fn read_async(self, ctx: &crate::GpuContext) -> impl std::future::Future<Output = Result<Vec<u8>, crate::error::SnowError>> + 'static {
        let mapped = MappedRead::new(&ctx.device, self.staging.clone());
        async move { Ok(self.unpad(&mapped.await?)) }
    }

    fn unpad(&self, bytes: &[u8]) -> Vec<u8> {
        let row = self.size.0 as usize * 4;
        let mut out = Vec::with_capacity(row * self.size.1 as usize);
        for y in 0..self.size.1 as usize {
            out.extend_from_slice(&bytes[y * self.padded_row as usize..][..row]);
        }
        out
    }
}
