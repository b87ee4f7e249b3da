// The flags a pass's pipeline is built for: `PASS_FLAGS`, set by the pass
// (one pipeline per set of flags in use, `pass::compute::ComputePass`);
// the default reads `params.flags`, which the importing pass declares (its
// uniforms, with a `flags: u32`). Built in, no branch tests a uniform alone:
// Mesa 22's lavapipe compiles such a shader again at every dispatch, the
// uniforms' values inlined, and keeps every copy (docs/deformation.md,
// "Branches on uniforms").

override PASS_FLAGS: u32 = 0xffffffffu;

fn pass_flags() -> u32 {
    if PASS_FLAGS != 0xffffffffu {
        return PASS_FLAGS;
    }
    return params.flags;
}
