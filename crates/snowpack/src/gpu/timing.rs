//! Per-pass GPU time from timestamp queries, read back through a ring (never
//! stalling), summarised as medians.

use std::collections::BTreeMap;

use super::readback::ReadbackRing;

/// Most passes one frame can time.
pub const MAX_TIMED_PASSES: u32 = 32;
/// Samples kept per pass (the newest).
const MAX_SAMPLES: usize = 4096;

/// Medians of per-pass GPU time, in milliseconds, in frame order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PassTimings {
    /// (pass label, median ms, samples).
    pub passes: Vec<(String, f64, usize)>,
}

impl PassTimings {
    /// Sum of the medians (ms).
    #[must_use]
    pub fn total_ms(&self) -> f64 {
        self.passes.iter().map(|p| p.1).sum()
    }
}

/// Writes a timestamp at the start and end of each pass it is asked about.
pub struct GpuTimer {
    query_set: Option<wgpu::QuerySet>,
    resolve: Option<wgpu::Buffer>,
    ring: Option<ReadbackRing<Vec<&'static str>>>,
    labels: Vec<&'static str>,
    order: Vec<&'static str>,
    period_ns: f64,
    samples: BTreeMap<&'static str, Vec<f64>>,
}

/// Median of a sample (sorted copy); `None` when empty.
#[must_use]
pub fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) })
}

impl GpuTimer {
    /// A timer; inert (no queries, no cost) when the device lacks timestamps.
    #[must_use]
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        let enabled = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let count = MAX_TIMED_PASSES * 2;
        let bytes = u64::from(count) * 8;
        let (query_set, resolve, ring) = if enabled {
            (
                Some(device.create_query_set(&wgpu::QuerySetDescriptor { label: Some("pass timestamps"), ty: wgpu::QueryType::Timestamp, count })),
                Some(device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("timestamp resolve"),
                    size: bytes,
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })),
                Some(ReadbackRing::new(device, "timestamps", bytes, 4)),
            )
        } else {
            (None, None, None)
        };
        Self { query_set, resolve, ring, labels: Vec::new(), order: Vec::new(), period_ns: f64::from(queue.get_timestamp_period()), samples: BTreeMap::new() }
    }

    /// A timer that records nothing (for one-off work outside the frame loop).
    #[must_use]
    pub fn disabled() -> Self {
        Self { query_set: None, resolve: None, ring: None, labels: Vec::new(), order: Vec::new(), period_ns: 1.0, samples: BTreeMap::new() }
    }

    /// Whether timestamps are recorded.
    #[must_use]
    pub fn enabled(&self) -> bool {
        self.query_set.is_some()
    }

    /// Starts a frame's list of timed passes.
    pub fn begin_frame(&mut self) {
        self.labels.clear();
    }

    /// Reserves the two timestamps of a pass; `None` when timing is off or the frame is full.
    pub fn reserve(&mut self, label: &'static str) -> Option<u32> {
        self.query_set.as_ref()?;
        let index = u32::try_from(self.labels.len()).ok()?;
        if index >= MAX_TIMED_PASSES {
            return None;
        }
        self.labels.push(label);
        if !self.order.contains(&label) {
            self.order.push(label);
        }
        Some(index)
    }

    /// Timestamp writes for a compute pass reserved with [`Self::reserve`].
    #[must_use]
    pub fn compute_writes(&self, slot: Option<u32>) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let (query_set, slot) = (self.query_set.as_ref()?, slot?);
        Some(wgpu::ComputePassTimestampWrites { query_set, beginning_of_pass_write_index: Some(slot * 2), end_of_pass_write_index: Some(slot * 2 + 1) })
    }

    /// Timestamp writes for a render pass reserved with [`Self::reserve`].
    #[must_use]
    pub fn render_writes(&self, slot: Option<u32>) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        let (query_set, slot) = (self.query_set.as_ref()?, slot?);
        Some(wgpu::RenderPassTimestampWrites { query_set, beginning_of_pass_write_index: Some(slot * 2), end_of_pass_write_index: Some(slot * 2 + 1) })
    }

    /// Resolves this frame's timestamps and queues their readback (mapped
    /// when `encoder` is submitted; [`Self::collect`] takes it later).
    pub fn end_frame(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let (Some(query_set), Some(resolve), Some(ring)) = (&self.query_set, &self.resolve, &mut self.ring) else {
            return;
        };
        if self.labels.is_empty() {
            return;
        }
        let count = self.labels.len() as u32 * 2;
        encoder.resolve_query_set(query_set, 0..count, resolve, 0);
        ring.record_copy(encoder, resolve, self.labels.clone());
    }

    /// Collects timestamps that have arrived (non-blocking; poll the device first).
    pub fn collect(&mut self) {
        let Some(ring) = &mut self.ring else { return };
        while let Some((labels, bytes)) = ring.take_latest() {
            let stamps: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes);
            // A pass recorded more than once in a frame (the capture's
            // compute and its draw) counts once: the sum of its parts.
            for (k, label) in labels.iter().enumerate() {
                if labels[..k].contains(label) {
                    continue;
                }
                let mut ms = 0.0;
                let mut whole = true;
                for (m, _) in labels.iter().enumerate().filter(|(_, l)| *l == label) {
                    let (start, end) = (stamps[2 * m], stamps[2 * m + 1]);
                    // A wrapped or missing stamp: skip the pass rather than invent.
                    whole &= end >= start;
                    ms += end.saturating_sub(start) as f64 * self.period_ns / 1e6;
                }
                if !whole {
                    continue;
                }
                let list = self.samples.entry(label).or_default();
                if list.len() == MAX_SAMPLES {
                    list.remove(0);
                }
                list.push(ms);
            }
        }
    }

    /// Whether readbacks are still outstanding.
    #[must_use]
    pub fn in_flight(&self) -> bool {
        self.ring.as_ref().is_some_and(ReadbackRing::in_flight)
    }

    /// Forgets collected samples (for example after warm-up).
    pub fn clear(&mut self) {
        self.samples.clear();
    }

    /// The newest GPU time per pass (the last frame whose timestamps came
    /// back), in first-seen order; the count is the samples kept so far.
    #[must_use]
    pub fn latest(&self) -> PassTimings {
        let passes = self
            .order
            .iter()
            .filter_map(|label| {
                let s = self.samples.get(label)?;
                Some(((*label).to_owned(), *s.last()?, s.len()))
            })
            .collect();
        PassTimings { passes }
    }

    /// Median GPU time per pass over the collected samples, in first-seen order.
    #[must_use]
    pub fn medians(&self) -> PassTimings {
        let passes = self
            .order
            .iter()
            .filter_map(|label| {
                let s = self.samples.get(label)?;
                Some(((*label).to_owned(), median(s)?, s.len()))
            })
            .collect();
        PassTimings { passes }
    }
}
