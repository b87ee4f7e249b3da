//! The memory traffic every deformation pass must cause each frame: the
//! bytes it reads and writes for every texel of the window whatever the
//! actors do. Divided by an adapter's memory bandwidth it is the pass's
//! physical floor, the time no implementation of the same algorithm on that
//! adapter can beat; the benchmark prints it beside the measured time.
//!
//! Counted: each per-texel access in the pass's WGSL that runs for every
//! texel, each texel once (workgroup tiles' halos, which caches serve, are
//! not counted). Not counted: accesses that depend on the actors (a stamp
//! written where a footprint refills, a point rim read where snow is
//! undisturbed), the stamp pass (its work is per point) and the window pass
//! (its work is per newly exposed texel, 8 bytes each).
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use super::technique::Technique;
use crate::SnowParams;
use crate::deform::params::SnowParamsExt;
use crate::deform::technique::TechniqueExt;

/// One pass's compulsory traffic per frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassTraffic {
    /// The pass, as GPU timings name it.
    pub pass: &'static str,
    /// Bytes read.
    pub read_bytes: u64,
    /// Bytes written.
    pub written_bytes: u64,
}

impl PassTraffic {
    /// Bytes read and written.
    #[must_use]
    pub fn total_bytes(&self) -> u64 {
        self.read_bytes + self.written_bytes
    }

    /// The floor (ms) at `bandwidth_gb_per_s` (10⁹ bytes per second).
    #[must_use]
    pub fn floor_ms(&self, bandwidth_gb_per_s: f64) -> f64 {
        self.total_bytes() as f64 / (bandwidth_gb_per_s * 1e9) * 1e3
    }
}

/// The compulsory traffic of each pass of one frame with `params`, in frame order.
#[must_use]
pub fn frame_traffic(params: &SnowParams) -> Vec<PassTraffic> {
    // One snow or stamp word.
    const WORD: u64 = 4;
    // One texel of the 16-bit capture.
    const DEPTH: u64 = 2;
    let n = params.texel_count() as u64;
    let captures = matches!(params.technique, Technique::Depth | Technique::Combined);
    let pass = |pass, read_per_texel: u64, written_per_texel: u64| PassTraffic { pass, read_bytes: n * read_per_texel, written_bytes: n * written_per_texel };
    let mut out = Vec::new();
    if captures {
        // The shapes' 16-bit codes are written whole by compute (the
        // meshes' depth target only with meshes: actor-dependent, not counted).
        out.push(pass("capture", 0, DEPTH));
    }
    // The terrain is evaluated from its source (flat and noise read nothing
    // per texel; a heightmap's samples are cached reads, not counted).
    let stamps = params.technique.uses_stamps();
    // update.wgsl: the snow word, the stamp word where the window has
    // footprints, the capture depth when capturing; the snow word back.
    out.push(pass("update", WORD + if stamps { WORD } else { 0 } + if captures { DEPTH } else { 0 }, WORD));
    // display.wgsl: the snow word, and the stamp word for point rims; the
    // word back with its displayed half. The blur's apron is re-read from
    // cache and workgroup memory, not counted; there is no normals pass.
    out.push(pass("display", WORD + if stamps { WORD } else { 0 }, WORD));
    out
}

/// Memory bandwidth (GB/s, 10⁹ bytes/s) of common GPUs from their makers'
/// data sheets, matched against an adapter's name (first match wins, so the
/// more specific names come first).
pub const KNOWN_BANDWIDTH_GB_PER_S: [(&str, f64); 16] = [
    ("H100 PCIe", 2000.0),
    ("H100 NVL", 3900.0),
    ("H100", 3350.0), // SXM5, HBM3
    ("H200", 4800.0),
    ("A100-PCIE-40GB", 1555.0),
    ("A100", 2039.0), // 80 GB SXM4
    ("L40", 864.0),   // L40 and L40S
    ("L4", 300.0),
    ("RTX 4090", 1008.0),
    ("RTX 4080", 717.0),
    ("RTX 3090", 936.0),
    ("RTX 3080", 760.0),
    ("RTX 3060", 360.0),
    ("RTX 2080 Ti", 616.0),
    ("RX 7900 XTX", 960.0),
    ("RX 6800 XT", 512.0),
];

/// The bandwidth of the adapter called `name`, when it is a known GPU.
#[must_use]
pub fn known_bandwidth_gb_per_s(name: &str) -> Option<f64> {
    KNOWN_BANDWIDTH_GB_PER_S.iter().find(|(pattern, _)| name.contains(pattern)).map(|(_, gb)| *gb)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_16x16_depth_frame_moves_what_a_hand_count_of_the_shaders_says() {
        let params = SnowParams { resolution: 16, extent_m: 1.0, technique: Technique::Depth, blur: true, ..SnowParams::default() };
        let frame = frame_traffic(&params);
        let by_name = |name: &str| *frame.iter().find(|p| p.pass == name).expect(name);
        // 256 texels: capture stores 256 16-bit depths; update reads capture
        // (2 B) and the snow word (4 B) and writes the word (4 B); display
        // reads and writes the word (the blur is in workgroup memory).
        assert_eq!(by_name("capture"), PassTraffic { pass: "capture", read_bytes: 0, written_bytes: 512 });
        assert_eq!(by_name("update"), PassTraffic { pass: "update", read_bytes: 1536, written_bytes: 1024 });
        assert_eq!(by_name("display"), PassTraffic { pass: "display", read_bytes: 1024, written_bytes: 1024 });
        assert_eq!(frame.iter().map(PassTraffic::total_bytes).sum::<u64>(), 256 * 20);
        // The points technique captures nothing, and reads the footprints twice.
        let points = frame_traffic(&SnowParams { technique: Technique::Points, blur: false, ..params });
        assert_eq!(points.iter().map(|p| p.pass).collect::<Vec<_>>(), ["update", "display"]);
        assert_eq!(points[1].read_bytes, 2048);
    }

    #[test]
    fn floors_follow_from_bandwidth() {
        let t = PassTraffic { pass: "update", read_bytes: 3_000_000_000, written_bytes: 350_000_000 };
        assert!((t.floor_ms(3350.0) - 1.0).abs() < 1e-9);
        assert_eq!(known_bandwidth_gb_per_s("NVIDIA H100 80GB HBM3"), Some(3350.0));
        assert_eq!(known_bandwidth_gb_per_s("NVIDIA H100 PCIe"), Some(2000.0));
        assert_eq!(known_bandwidth_gb_per_s("llvmpipe (LLVM 15.0.6, 256 bits)"), None);
    }
}
