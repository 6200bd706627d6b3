// Hybrid ambient occlusion: what the trace pass and the CPU twin (`bevy_hao::cpu::ao`) share: the settings,
// the ray directions (cosine-weighted, stratified, rotated per pixel), the distance falloff, and the march
// through the voxel texture with empty-space skipping on its max-reduced mips.
#define_import_path bevy_hao::hao_common

// src/ao/prepare.rs: `GpuHaoSettings`
struct HaoSettings {
    grid_origin: vec3<f32>,
    cell_size: f32,
    grid_dims: vec3<u32>,
    mip_levels: u32,
    rays: u32,
    steps: u32,
    max_distance: f32,
    falloff: f32,
    intensity: f32,
    start_offset: f32,
    grid_valid: u32,
    frame: u32,
    near_field: u32,
    half_resolution: u32,
    denoise_radius: u32,
    _pad: u32,
}

const PI: f32 = 3.141592653589793;
const GOLDEN: f32 = 0.6180339887498949;

// cpu/ao.rs: interleaved_gradient_noise (Jimenez 2014), in [0, 1).
fn interleaved_gradient_noise(pixel: vec2<f32>, frame: u32) -> f32 {
    let p = pixel + 5.588238 * f32(frame % 64u);
    return fract(52.9829189 * fract(0.06711056 * p.x + 0.00583715 * p.y));
}

// cpu/ao.rs: orthonormal_basis (Duff et al. 2017): two tangents completing `n`.
fn orthonormal_basis(n: vec3<f32>) -> mat3x3<f32> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    let t = vec3<f32>(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    let bt = vec3<f32>(b, s + n.y * n.y * a, -n.y);
    return mat3x3<f32>(t, bt, n);
}

// cpu/ao.rs: hemisphere_direction. Ray `i` of `count`, cosine-weighted around the normal (the third column
// of `basis`, from `orthonormal_basis`) and stratified in the polar coordinate; `rotation` (two numbers in
// [0, 1)) shifts the whole set per pixel.
fn hemisphere_direction(basis: mat3x3<f32>, i: u32, count: u32, rotation: vec2<f32>) -> vec3<f32> {
    let u1 = fract((f32(i) + rotation.x) / f32(count));
    let u2 = fract(f32(i) * GOLDEN + rotation.y);
    let r = sqrt(u1);
    let phi = 2.0 * PI * u2;
    let local = vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u1)));
    return basis * local;
}

// cpu/ao.rs: ao_falloff. The weight of an occluder at `distance`: 1 near the surface, 0 at `max_distance`
// and beyond, `(1 - d / max)^falloff` between.
fn ao_falloff(distance: f32, max_distance: f32, falloff: f32) -> f32 {
    let x = clamp(distance / max_distance, 0.0, 1.0);
    return pow(1.0 - x, falloff);
}

// The [t_enter, t_exit] of a ray (grid space) in the box [lo, hi]; empty if t_enter > t_exit.
fn ray_box(origin: vec3<f32>, inv_dir: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>) -> vec2<f32> {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    let tmin = min(t0, t1);
    let tmax = max(t0, t1);
    return vec2<f32>(max(max(tmin.x, tmin.y), tmin.z), min(min(tmax.x, tmax.y), tmax.z));
}

// cpu/ao.rs: safe_inverse. 1 / d with zero components replaced by a huge value of the same sign.
fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    let big = vec3<f32>(1.0e30);
    let s = select(vec3<f32>(-1.0), vec3<f32>(1.0), d >= vec3<f32>(0.0));
    return select(1.0 / d, s * big, abs(d) < vec3<f32>(1.0e-30));
}

// cpu/ao.rs: VoxelMips level sizes. The voxel texture's size at `level`: the grid's dimensions rounded up
// to a multiple of the coarsest texel (2^(mip_levels - 1) cells), halved `level` times. (Computed, not
// queried: Mesa 22's lavapipe returns wrong textureDimensions for levels >= 2 of 3D textures.)
fn voxel_level_size(grid_dims: vec3<u32>, mip_levels: u32, level: u32) -> vec3<u32> {
    let align = 1u << (mip_levels - 1u);
    let padded = (grid_dims + vec3<u32>(align - 1u)) / align * align;
    return padded >> vec3<u32>(level);
}

// cpu/ao.rs: VoxelMips::march_voxels. The distance along `dir` (grid units, from `origin`) to the first
// occupied cell within [t_start, t_end], or -1: start at mip level `start_level`, step over empty texels
// whole, descend into occupied ones; at most `steps` texel visits.
fn march_voxels(
    voxels: texture_3d<f32>,
    grid_dims: vec3<u32>,
    mip_levels: u32,
    origin: vec3<f32>,
    dir: vec3<f32>,
    t_start: f32,
    t_end: f32,
    start_level: u32,
    steps: u32,
) -> f32 {
    let inv = safe_inverse(dir);
    let span = ray_box(origin, inv, vec3<f32>(0.0), vec3<f32>(grid_dims));
    var t = max(t_start, span.x);
    let t_max = min(t_end, span.y);
    let top = mip_levels - 1u;
    var level = min(start_level, top);
    for (var i = 0u; i < steps; i++) {
        if t > t_max {
            return -1.0;
        }
        let p = origin + dir * t;
        let size = vec3<i32>(voxel_level_size(grid_dims, mip_levels, level));
        let scale = f32(1u << level);
        let texel = clamp(vec3<i32>(floor(p * (1.0 / scale))), vec3<i32>(0), size - vec3<i32>(1));
        if textureLoad(voxels, texel, i32(level)).r > 0.0 {
            if level == 0u {
                return t;
            }
            level -= 1u;
        } else {
            let lo = vec3<f32>(texel) * scale;
            let exit = ray_box(origin, inv, lo, lo + vec3<f32>(scale)).y;
            t = max(exit, t) + 1.0e-3;
            level = min(level + 1u, top);
        }
    }
    return -1.0;
}

// Octahedral encoding of a unit vector into [-1, 1]^2 (for the denoiser's packed normals).
fn octahedral_encode(n: vec3<f32>) -> vec2<f32> {
    let p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if n.z >= 0.0 {
        return p;
    }
    return (1.0 - abs(p.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
}

fn octahedral_decode(e: vec2<f32>) -> vec3<f32> {
    var n = vec3<f32>(e, 1.0 - abs(e.x) - abs(e.y));
    let t = max(-n.z, 0.0);
    n.x += select(t, -t, n.x >= 0.0);
    n.y += select(t, -t, n.y >= 0.0);
    return normalize(n);
}

// The denoiser's weight of a tap `offset` texels away with view depth `depth` and normal `normal`, against
// the center's: a Gaussian in distance, falling with the relative depth difference and the normals' angle.
fn bilateral_weight(offset: f32, radius: f32, center_depth: f32, depth: f32, center_normal: vec3<f32>, normal: vec3<f32>) -> f32 {
    let spatial = exp(-offset * offset / (2.0 * max(radius * radius, 1.0)));
    let depth_w = exp(-abs(depth - center_depth) / (0.02 * abs(center_depth) + 1.0e-4));
    let c = max(dot(center_normal, normal), 0.0);
    let c2 = c * c;
    let c4 = c2 * c2;
    let c8 = c4 * c4;
    return spatial * depth_w * c8 * c8;
}
