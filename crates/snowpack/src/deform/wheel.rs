//! Wheels ([`crate::Deformer::Wheel`]): a tyre with a tread, rolling about its axle.
//! The geometry lives in `snowpack_share::replicate::press::wheel` (a machine without a
//! GPU presses wheels the same way); this module re-exports it.
//!
//! The tyre is a cylinder of the outer radius `r` (lugs included) and width
//! `2 half_width` around the axle; the tread is a pattern over its surface in
//! the coordinates `(s, u)`: `s` the arc length around the tyre at the outer
//! radius, `u` across it (−1 to 1 from one side to the other). Where the
//! pattern has a lug the surface is at `r`, elsewhere (the tyre's grooves) at
//! `r − depth_m`, so raised lugs press grooves into the floor of the rut and
//! the snow between them stays as ridges.
//!
//! The arc coordinate of a point on the tyre at angle θ ahead of its lowest
//! point (towards [`forward`]) is `s = roll_m + r θ`: rolling without slip a
//! distance `D` turns the tyre by `D / r`, so `roll_m` grows by `D` and the
//! tread touching the snow stays where it touched, whatever the frame rate.
//! With slip the tread turns `1 + slip` times as fast (`slip = −1`: a locked
//! wheel sliding): the contact moves over the snow and the sub-steps of the
//! sweep smear the pattern along the rut.
//!
//! The capture ray casts one tyre per sub-step (`shared/capture_shapes.wgsl`,
//! CPU twin `cpu::capture_shapes::wheel_bottom`); the sub-steps are spaced so
//! that neither the tyre nor its tread at the contact moves more than
//! one texel between them (`snowpack_share::replicate::press::sweep`).

#[cfg_attr(
    not(feature = "low_level"),
    allow(unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]
pub use snowpack_share::replicate::press::wheel::{Tread, TreadPattern, WheelPose, extent_below, forward, instance};
