// Debug views of a camera (src/debug/mod.rs: `HaoDebugView`), drawn over its final image: the ambient
// occlusion alone, or the voxel grid ray-marched from the camera (voxels as shaded boxes, their point counts
// as a heat map, static and dynamic voxels in two colors, their cascade, or their average albedo or normal).
#import bevy_render::view::View
#import bevy_hao::voxel_grid::{
    voxel_grid, finest_level_containing, march_cascades, level_position, voxel_albedo_at, voxel_normal_at,
    voxel_texel,
}
#import bevy_hao::gi_common::unpack_rgb9e5

struct DebugSettings {
    mode: u32,
    // Words of a voxel's record in `point_counts` (0: none).
    sample_words: u32,
    has_ao: u32,
    _pad: u32,
}

const MODE_AO: u32 = 1u;
const MODE_VOXELS: u32 = 2u;
const MODE_POINT_COUNTS: u32 = 3u;
const MODE_STATIC_DYNAMIC: u32 = 4u;
const MODE_CASCADES: u32 = 5u;
const MODE_ALBEDO: u32 = 6u;
const MODE_NORMALS: u32 = 7u;
const MODE_LIT: u32 = 8u;

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> occupancy: array<u32>;
@group(0) @binding(2) var<storage, read> static_occupancy: array<u32>;
@group(0) @binding(3) var<storage, read> point_counts: array<u32>;
@group(0) @binding(4) var ambient_occlusion: texture_2d<f32>;
@group(0) @binding(5) var<uniform> settings: DebugSettings;
@group(0) @binding(6) var source: texture_2d<f32>;
// Voxel GI's lighting volume (rgb9e5 words laid out as the voxel texture's mip 0), or a 1x1x1 placeholder.
@group(0) @binding(7) var radiance: texture_3d<u32>;
// The voxel levels are bound at group 2 (`bevy_hao::voxel_grid`).

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

fn bit(words_static: bool, index: u32) -> bool {
    if words_static {
        return ((static_occupancy[index >> 5u] >> (index & 31u)) & 1u) == 1u;
    }
    return ((occupancy[index >> 5u] >> (index & 31u)) & 1u) == 1u;
}

// A compact rainbow (blue, cyan, green, yellow, red) for the heat map.
fn heat(x: f32) -> vec3<f32> {
    let t = clamp(x, 0.0, 1.0) * 4.0;
    let c = vec3<f32>(clamp(t - 2.0, 0.0, 1.0), clamp(select(t, 4.0 - t, t > 2.0), 0.0, 1.0), clamp(2.0 - t, 0.0, 1.0));
    return c;
}

@fragment
fn fragment(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    let scene = textureLoad(source, vec2<i32>(in.position.xy), 0);
    if settings.mode == MODE_AO {
        if settings.has_ao == 0u {
            return vec4<f32>(1.0, 0.0, 1.0, 1.0);
        }
        let ao = textureLoad(ambient_occlusion, vec2<i32>(in.position.xy), 0).r;
        return vec4<f32>(vec3<f32>(ao), 1.0);
    }
    if voxel_grid.level_count == 0u {
        return scene * 0.25;
    }
    // A primary ray through the pixel, from the camera (a perspective view) or from the near plane along
    // the view direction (an orthographic one).
    let ndc = vec2<f32>(in.uv.x * 2.0 - 1.0, 1.0 - in.uv.y * 2.0);
    let near4 = view.world_from_clip * vec4<f32>(ndc, 1.0, 1.0);
    let far4 = view.world_from_clip * vec4<f32>(ndc, 1.0e-6, 1.0);
    let near = near4.xyz / near4.w;
    let dir_world = normalize(far4.xyz / far4.w - near);
    let start = finest_level_containing(near);
    let hit = march_cascades(near, dir_world, start, 0.0, 1.0e30, 1024u);
    if hit.x < 0.0 {
        return vec4<f32>(scene.rgb * 0.2, 1.0);
    }
    let level = u32(hit.y);
    let l = voxel_grid.levels[level];
    let t = hit.x / l.cell_size;
    let origin = level_position(level, near);
    let entry = origin + dir_world * t;
    let cell = vec3<u32>(clamp(vec3<i32>(floor(origin + dir_world * (t + 1.0e-3))), vec3<i32>(0), vec3<i32>(l.dims) - vec3<i32>(1)));
    // The face the ray entered through: the coordinate closest to a cell face.
    let f = abs(entry - round(entry));
    var shade = 0.55;
    var uv = entry.xy;
    if f.x <= f.y && f.x <= f.z {
        shade = 0.75;
        uv = entry.yz;
    } else if f.y <= f.z {
        shade = 1.0;
        uv = entry.xz;
    }
    // Cell edges as lines, so voxels read as boxes.
    let e = abs(fract(uv) - 0.5);
    let edge = select(1.0, 0.7, max(e.x, e.y) > 0.44);
    let physical = (cell + l.wrap) % l.dims;
    let index = level * l.dims.x * l.dims.y * l.dims.z + physical.x + l.dims.x * (physical.y + l.dims.y * physical.z);
    var color = vec3<f32>(0.92, 0.9, 0.85);
    if settings.mode == MODE_POINT_COUNTS {
        if settings.sample_words != 0u {
            let n = f32(point_counts[index * settings.sample_words]);
            color = heat(log2(n + 1.0) / 8.0);
        } else {
            color = vec3<f32>(0.5);
        }
    } else if settings.mode == MODE_STATIC_DYNAMIC {
        color = select(vec3<f32>(1.0, 0.55, 0.15), vec3<f32>(0.35, 0.6, 1.0), bit(true, index));
    } else if settings.mode == MODE_CASCADES {
        color = heat(f32(level) / 4.0) * 0.7 + vec3<f32>(0.3);
    } else if settings.mode == MODE_ALBEDO || settings.mode == MODE_NORMALS {
        // Grey without attributes; a voxel without points (a solid's inside): magenta in the albedo view,
        // black in the normals view (no unit normal is drawn darker than 0.2).
        color = vec3<f32>(0.5);
        if voxel_grid.attributes != 0u {
            let albedo = voxel_albedo_at(level, vec3<i32>(cell));
            if albedo.a == 0.0 {
                color = select(vec3<f32>(0.03), vec3<f32>(0.8, 0.2, 0.8), settings.mode == MODE_ALBEDO);
            } else if settings.mode == MODE_ALBEDO {
                color = albedo.rgb;
            } else {
                // Unshaded: the normal's components as colors.
                return vec4<f32>((voxel_normal_at(level, vec3<i32>(cell)) * 0.5 + 0.5) * edge, 1.0);
            }
        }
    }
    if settings.mode == MODE_LIT {
        if textureDimensions(radiance).x <= 1u {
            return vec4<f32>(vec3<f32>(0.5) * shade * edge, 1.0);
        }
        // Unshaded: the light in the voxel as the view's exposure shows it, tone-mapped.
        let r = unpack_rgb9e5(textureLoad(radiance, voxel_texel(level, vec3<i32>(cell)), 0).r) * view.exposure;
        return vec4<f32>((r / (vec3<f32>(1.0) + r) + vec3<f32>(0.02)) * edge, 1.0);
    }
    return vec4<f32>(color * shade * edge, 1.0);
}
