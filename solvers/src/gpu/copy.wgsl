// Copy-bandwidth probe: dst[i] = src[i] over vec4<f32> elements, one element per thread.
// The element index is spread over x and y so that large buffers stay within the
// per-dimension dispatch limit. Mirrors `gpu::bandwidth::CopyParams`; the bindings are
// declared in `gpu::bandwidth::SPEC` and checked by `tests/kernel_contract.rs`.

struct CopyParams {
    len: u32,        // number of vec4 elements
    row: u32,        // threads per dispatch row (x workgroups * 256)
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> P: CopyParams;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<f32>>;

@compute @workgroup_size(256, 1, 1)
fn copy(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * P.row;
    if (i < P.len) {
        dst[i] = src[i];
    }
}
