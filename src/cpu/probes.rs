//! The irradiance probes of voxel global illumination (WGSL `gi_probes.wgsl`): a grid of probes following
//! the camera, each gathering the lighting volume's light ([`super::lighting::voxel_radiance`]) along rays
//! through the voxels, into the six faces of an ambient cube as Bevy's irradiance volume holds them.
//!
//! * The grid: probe `q` (a lattice point, `q * spacing` in world space) for `q` in a window of
//!   `counts` probes around the camera, snapped to the spacing ([`probe_window`]), stored toroidally so that
//!   a probe keeps its history while the window scrolls ([`ProbeWindow::slot`]).
//! * A probe in a voxel moves out of it along the average normal of the voxels around it before it gathers
//!   ([`relocate_probe`], [`neighbourhood_normal`]): a probe inside a floor or a wall would see its own
//!   surface from inside.
//! * Each face is gathered where the surfaces that read it are ([`face_origin`]): Bevy reads a probe's face
//!   for every surface facing that way within a spacing of it. A surface behind the probe that faces that
//!   way reads it: the face is gathered half a cell in front of it, where that surface's light is (a wall's
//!   foot beside a sunlit floor). A face whose way is shut by a surface within a spacing is read by the
//!   surfaces beyond it: it is gathered from there; gathered from the probe, a thin wall's lit side would
//!   light the room behind it (light leaking, the known failure of probe grids).
//! * Its rays cover the sphere evenly ([`sphere_direction`]), turned at random on each update
//!   ([`probe_rotation`]); a ray that stops in a voxel takes the voxel's radiance where the voxel's average
//!   normal faces it (a voxel seen from behind holds faces the probe does not see), nothing where it does
//!   not; a ray that leaves the volume or runs out of steps brings no light (the sky is Bevy's
//!   `GlobalAmbientLight`, added by Bevy's PBR on top).
//! * The faces hold the irradiance over pi (cd/m^2): what a white Lambertian surface facing each way sends
//!   out, the value Bevy's PBR multiplies by the diffuse colour ([`gather_probe`]).
//! * Each update blends into the probe's history, up to a window of frames ([`blend_probe`]); near
//!   occluders that moved, a shorter one ([`moved_cap`]).
//! * The probes are written into the irradiance volume faded out over the window's last spacings
//!   ([`ProbeWindow::edge_fade`]), so that the indirect light ends without a seam.

use super::march::{TraceLevel, finest_level_containing, march_cascades};
use super::temporal::MovedVoxels;
use glam::{IVec3, UVec3, Vec2, Vec3};
use std::f32::consts::PI;

/// The faces of an ambient cube, in the order Bevy's irradiance volume and the probes' records hold them:
/// +x, -x, +y, -y, +z, -z.
pub const PROBE_FACES: [Vec3; 6] = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z];

/// The lanes of a probe's workgroup on the GPU (WGSL `PROBE_LANES`): lane `j` traces the rays `k = j, j +
/// PROBE_LANES, ...`, and [`gather_probe`] sums them in that order, each lane's rays and then the lanes.
pub const PROBE_LANES: u32 = 8;

/// The most texel visits a probe's ray makes (WGSL `PROBE_STEPS`).
pub const PROBE_STEPS: u32 = 64;

/// How far a probe's rays look, world units (WGSL `PROBE_MAX_DISTANCE`): past the volume, in effect.
pub const PROBE_MAX_DISTANCE: f32 = 1.0e4;

/// The most a probe in a voxel moves out of it along the voxel's normal, in probe spacings (WGSL
/// `RELOCATE_MAX`): under half, so that it stays nearer its own lattice point than any other's.
pub const RELOCATE_MAX: f32 = 0.45;

/// How far a face looks for a surface to gather from beyond, in probe spacings (WGSL `FACE_REACH`): as far
/// as the surfaces Bevy reads the face for.
pub const FACE_REACH: f32 = 1.0;

/// The most texel visits of a face's march toward a surface (WGSL `FACE_STEPS`).
pub const FACE_STEPS: u32 = 16;

/// The most half-cell steps a face's origin takes through a surface's voxels to the far side (WGSL
/// `FACE_EXIT_STEPS`).
pub const FACE_EXIT_STEPS: u32 = 16;

/// The golden ratio's fractional part.
const GOLDEN: f32 = 0.618_034;

/// The probes of a frame: lattice points `min .. min + counts`, `spacing` apart, around `focus`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeWindow {
    /// The lattice point of the window's first probe.
    pub min: IVec3,
    /// Probes along each axis.
    pub counts: UVec3,
    /// World distance between neighbouring probes.
    pub spacing: f32,
    /// The world point the window follows (the camera), which its probes fade out away from
    /// ([`ProbeWindow::edge_fade`]).
    pub focus: Vec3,
}

/// The probe spacings over which a window's probes fade out toward its edges ([`ProbeWindow::edge_fade`]),
/// at most half the window's reach.
pub const EDGE_FADE_SPACINGS: f32 = 2.0;

/// The window of `counts` probes `spacing` apart around `focus`, snapped to the spacing (its middle probe
/// the lattice point nearest `focus`), or `None` for a focus that is not finite or too far out for the
/// lattice (`i32`).
pub fn probe_window(focus: Vec3, spacing: f32, counts: UVec3) -> Option<ProbeWindow> {
    let nearest = (focus / spacing).round();
    // Within 2^22 lattice points of the origin, where f32 still tells a probe from its neighbour by a fraction.
    if !(nearest.is_finite() && nearest.abs().max_element() < 4_194_304.0 && spacing > 0.0) {
        return None;
    }
    Some(ProbeWindow { min: nearest.as_ivec3() - (counts / 2).as_ivec3(), counts, spacing, focus })
}

impl ProbeWindow {
    /// Probes in the window.
    pub fn len(&self) -> u32 {
        self.counts.x * self.counts.y * self.counts.z
    }

    /// Whether the window holds no probe.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The lattice point of the window's `i`-th probe (x fastest).
    pub fn lattice(&self, i: u32) -> IVec3 {
        let c = self.counts;
        self.min + UVec3::new(i % c.x, i / c.x % c.y, i / (c.x * c.y)).as_ivec3()
    }

    /// A lattice point's world position.
    pub fn position(&self, q: IVec3) -> Vec3 {
        q.as_vec3() * self.spacing
    }

    /// Where lattice point `q`'s record is kept (WGSL `probe_slot`): `q` modulo the counts, x fastest, so that
    /// a probe keeps its slot while the window scrolls.
    pub fn slot(&self, q: IVec3) -> u32 {
        let s = q.rem_euclid(self.counts.as_ivec3()).as_uvec3();
        s.x + self.counts.x * (s.y + self.counts.y * s.z)
    }

    /// The weight lattice point `q`'s faces are written with into the irradiance volume (WGSL
    /// `edge_fade`): 1 near the focus, falling linearly to 0 over the last [`EDGE_FADE_SPACINGS`] spacings
    /// (at most half) of the window's reach on each axis (the product over the axes), so that the outermost
    /// probes, which Bevy's PBR applies out to the window's bounds, hold nothing, and the indirect light
    /// meets the nothing beyond them without a seam, also as the window moves with the focus (with far
    /// probes, the near light fades into theirs instead: `cpu::far_probes::near_texel`). The reach on an
    /// axis of `c` probes is `ceil(c / 2) - 1.5` spacings, which the outermost probes lie at or beyond
    /// wherever the focus is in its lattice cell; an axis of fewer than 4 probes does not fade.
    pub fn edge_fade(&self, q: IVec3) -> f32 {
        let d = (q.as_vec3() - self.focus / self.spacing).abs();
        let fade = |c: u32, d: f32| {
            if c < 4 {
                return 1.0;
            }
            let reach = c.div_ceil(2) as f32 - 1.5;
            ((reach - d) / EDGE_FADE_SPACINGS.min(0.5 * reach)).clamp(0.0, 1.0)
        };
        fade(self.counts.x, d.x) * fade(self.counts.y, d.y) * fade(self.counts.z, d.z)
    }

    /// The world box Bevy's `LightProbe` must cover for its texels' centres to lie on the probes: half a
    /// spacing beyond the first and last probe on each axis.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let lo = (self.min.as_vec3() - Vec3::splat(0.5)) * self.spacing;
        (lo, lo + self.counts.as_vec3() * self.spacing)
    }
}

/// A 32-bit integer hash (PCG's output permutation; WGSL `pcg_hash`).
pub fn pcg_hash(x: u32) -> u32 {
    let state = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// The rotation of the rays of the probe in slot `slot` on the update numbered `seed` (WGSL
/// `probe_rotation`): two numbers in `[0, 1)` from hashes, exact in `f32`.
pub fn probe_rotation(slot: u32, seed: u32) -> Vec2 {
    let a = pcg_hash(slot ^ pcg_hash(seed));
    let b = pcg_hash(a);
    Vec2::new((a >> 8) as f32, (b >> 8) as f32) / 16_777_216.0
}

/// Ray `k` of `count` over the sphere (WGSL `sphere_direction`): stratified in height, spread by the golden
/// angle around it, the whole set turned by `rotation`.
pub fn sphere_direction(k: u32, count: u32, rotation: Vec2) -> Vec3 {
    let u1 = ((k as f32 + rotation.x) / count as f32).fract();
    let z = 1.0 - 2.0 * u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * (k as f32 * GOLDEN + rotation.y).fract();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// What a probe's ray reads of a voxel: its radiance (the lighting volume) and its average normal.
pub trait LitVoxels {
    /// The radiance (cd/m^2) and average normal of cell `cell` of level `level`'s window.
    fn voxel(&self, level: usize, cell: IVec3) -> (Vec3, Vec3);
}

/// The cell of level `level`'s window that holds the point `t` (world) along a ray from `origin`: the cell it
/// enters there, a thousandth of a cell on (WGSL `hit_cell`).
pub fn hit_cell(levels: &[TraceLevel], level: usize, origin: Vec3, dir: Vec3, t: f32) -> IVec3 {
    let l = &levels[level];
    let p = l.level_position(origin) + dir * (t / l.cell_size + 1.0e-3);
    p.floor().as_ivec3().clamp(IVec3::ZERO, l.mips.dims().as_ivec3() - IVec3::ONE)
}

/// Whether the world point `q` lies in an occupied cell of `level`'s window (WGSL `occupied_at`): outside the
/// window, no.
pub fn occupied_at(level: &TraceLevel, q: Vec3) -> bool {
    let c = level.level_position(q).floor();
    c.cmpge(Vec3::ZERO).all() && c.cmplt(level.mips.dims().as_vec3()).all() && level.mips.occupied(c.as_ivec3())
}

/// Where the probe at lattice position `p` gathers from (WGSL `relocate_probe`): `p` itself, unless it lies
/// in an occupied voxel of the finest level that holds it whose neighbourhood's normal has a direction
/// ([`neighbourhood_normal`] at least [`super::lighting::SHADOW_NORMAL_MIN`] long); then the first point
/// along that normal, a cell at a time, whose voxel is empty, at most [`RELOCATE_MAX`] spacings away (there,
/// if none is).
pub fn relocate_probe(levels: &[TraceLevel], voxels: &impl LitVoxels, p: Vec3, spacing: f32) -> Vec3 {
    let level = finest_level_containing(levels, p);
    let l = &levels[level];
    let occupied = |q: Vec3| occupied_at(l, q);
    if !occupied(p) {
        return p;
    }
    let normal = neighbourhood_normal(levels, voxels, level, l.level_position(p).floor().as_ivec3());
    if normal.length() < super::lighting::SHADOW_NORMAL_MIN {
        return p;
    }
    let n = normal.normalize();
    let reach = RELOCATE_MAX * spacing;
    let steps = (reach / l.cell_size).floor().max(1.0) as u32;
    let step = reach / steps as f32;
    for k in 1..=steps {
        let q = p + n * (step * k as f32);
        if !occupied(q) {
            return q;
        }
    }
    p + n * reach
}

/// The mean of the average normals of the occupied cells among cell `cell` of level `level`'s window and its
/// 26 neighbours (WGSL `neighbourhood_normal`): the way a probe in that cell moves out. A voxel's own normal
/// is not enough where surfaces meet: in a room's corner the faces hidden in the joint (a wall's bottom face
/// on the floor's top) cancel part of it, and what is left may point into the floor; the floor's and the
/// wall's voxels beside it face the room. Both faces of a thin wall cancel in each of its voxels, and the
/// mean stays short: such a probe does not move.
pub fn neighbourhood_normal(levels: &[TraceLevel], voxels: &impl LitVoxels, level: usize, cell: IVec3) -> Vec3 {
    let l = &levels[level];
    let dims = l.mips.dims().as_ivec3();
    let (mut sum, mut count) = (Vec3::ZERO, 0u32);
    for z in -1..=1 {
        for y in -1..=1 {
            for x in -1..=1 {
                let c = cell + IVec3::new(x, y, z);
                if c.cmpge(IVec3::ZERO).all() && c.cmplt(dims).all() && l.mips.occupied(c) {
                    sum += voxels.voxel(level, c).1;
                    count += 1;
                }
            }
        }
    }
    sum / count.max(1) as f32
}

/// Where a probe at `p` gathers its face along `axis` (one of [`PROBE_FACES`]) from (WGSL `face_origin`): where
/// the surfaces that read that face are. Bevy reads a probe's face for every surface facing that way within a
/// spacing of it (trilinear, with no visibility test), so:
/// * a surface behind the probe (a march from `p` against `axis` stops within [`FACE_REACH`] spacings in a
///   voxel whose average normal, at least [`super::lighting::SHADOW_NORMAL_MIN`] long, faces along `axis`)
///   reads it: the face gathers from half a cell in front of that voxel, where that surface sees what it sees
///   (the light a wall takes from the floor at its foot, which a probe half a spacing out sees from behind);
/// * else a surface ahead (a run of occupied voxels stops a march along `axis` within [`FACE_REACH`]
///   spacings) stands between the probe and the surfaces facing that way beyond it (a thin wall's other
///   side), which read it: it gathers from the first point past that run, half a cell at a time (at most
///   [`FACE_EXIT_STEPS`]), whose voxel is empty;
/// * where both stop, the nearer of the two; where neither does, or no empty point is found, `p`.
pub fn face_origin(levels: &[TraceLevel], voxels: &impl LitVoxels, p: Vec3, axis: Vec3, spacing: f32) -> Vec3 {
    let start = finest_level_containing(levels, p);
    let reach = FACE_REACH * spacing;
    let ahead = march_cascades(levels, p, axis, start, 0.0, reach, FACE_STEPS);
    if let Some((t, level)) = march_cascades(levels, p, -axis, start, 0.0, reach, FACE_STEPS)
        && ahead.is_none_or(|(ahead, _)| t < ahead)
    {
        let normal = voxels.voxel(level, hit_cell(levels, level, p, -axis, t)).1;
        if normal.length() >= super::lighting::SHADOW_NORMAL_MIN && normal.dot(axis) > 0.0 {
            return p - axis * (t - 0.5 * levels[level].cell_size);
        }
    }
    let Some((t, level)) = ahead else {
        return p;
    };
    let l = &levels[level];
    let step = 0.5 * l.cell_size;
    for k in 1..=FACE_EXIT_STEPS {
        let q = p + axis * (t + step * k as f32);
        if !occupied_at(l, q) {
            return q;
        }
    }
    p
}

/// The light one ray brings to a probe at `p` along `dir` (WGSL `probe_ray_radiance`): the radiance of the
/// voxel it stops in where that voxel's average normal faces the ray, else nothing.
pub fn probe_ray_radiance(levels: &[TraceLevel], voxels: &impl LitVoxels, p: Vec3, dir: Vec3) -> Vec3 {
    let start = finest_level_containing(levels, p);
    let Some((t, level)) = march_cascades(levels, p, dir, start, 0.0, PROBE_MAX_DISTANCE, PROBE_STEPS) else {
        return Vec3::ZERO;
    };
    let (radiance, normal) = voxels.voxel(level, hit_cell(levels, level, p, dir, t));
    if normal.dot(dir) < 0.0 { radiance } else { Vec3::ZERO }
}

/// One update of a probe at `p`, `spacing` from its neighbours (WGSL `gather_probe`): `rays` rays over the
/// sphere turned by `rotation`, projected on the six faces of [`PROBE_FACES`] as irradiance over pi,
/// `4 / rays * sum(L * max(d . a, 0))`, each face's rays from its [`face_origin`] (traced once from `p` for
/// the faces that gather there), summed in the GPU's order ([`PROBE_LANES`]).
pub fn gather_probe(
    levels: &[TraceLevel],
    voxels: &impl LitVoxels,
    p: Vec3,
    spacing: f32,
    rays: u32,
    rotation: Vec2,
) -> [Vec3; 6] {
    let origins = PROBE_FACES.map(|axis| face_origin(levels, voxels, p, axis, spacing));
    // Each lane's sums of its rays, then the lanes', in the GPU's order.
    let mut faces = [Vec3::ZERO; 6];
    for lane in 0..PROBE_LANES {
        let mut lane_faces = [Vec3::ZERO; 6];
        for k in (lane..rays).step_by(PROBE_LANES as usize) {
            let d = sphere_direction(k, rays, rotation);
            let mut here = None;
            for ((face, axis), origin) in lane_faces.iter_mut().zip(PROBE_FACES).zip(origins) {
                let w = d.dot(axis);
                if w <= 0.0 {
                    continue;
                }
                let l = if origin == p {
                    *here.get_or_insert_with(|| probe_ray_radiance(levels, voxels, p, d))
                } else {
                    probe_ray_radiance(levels, voxels, origin, d)
                };
                *face += l * w;
            }
        }
        for (face, lane_face) in faces.iter_mut().zip(lane_faces) {
            *face += lane_face;
        }
    }
    faces.map(|f| f * (4.0 / rays as f32))
}

/// A probe's history after an update (WGSL `blend_probe`): the mean of its last updates, up to
/// `max_frames` of them (an exponential average beyond), and the updates it now holds; a history of one
/// update is that update, exactly (whatever the slot held before).
pub fn blend_probe(history: [Vec3; 6], frames: u32, update: [Vec3; 6], max_frames: u32) -> ([Vec3; 6], u32) {
    let n = (frames + 1).min(max_frames.max(1));
    if n == 1 {
        return (update, 1);
    }
    let w = 1.0 / n as f32;
    (std::array::from_fn(|k| history[k] + (update[k] - history[k]) * w), n)
}

/// How far a moved occluder reaches over the probes' histories (WGSL `MOVED_REACH_RADII`): a probe within
/// this many of its box's mean half-extents, plus a probe spacing, of the box ([`moved_cap`]). Farther, a
/// box covers under a fortieth of the probe's sphere and its change is within the history's noise.
pub const MOVED_REACH_RADII: f32 = 2.0;

/// The updates a probe at `p` holds at most where occluders moved near it (WGSL `moved_cap` in
/// `gi_probes.wgsl`), with `max_frames` the cap elsewhere and `phases` the frames between its updates (a
/// probe in `phases` is updated a frame). For each moved box ([`MovedVoxels`], as the voxel grid lists
/// them: the box around it now and last frame, held for a few frames after it stops) within
/// [`MOVED_REACH_RADII`] mean half-extents plus a `spacing` of the probe, the history its change allows:
/// `u` the updates it takes the occluder, at the speed it last moved, to move as far as it is from the probe
/// (at least a spacing), and `c` the share of the probe's view it covers (a sphere of its mean half-extent
/// `r` at the box's centre, `dc` away: `(r / dc)^2`, 1 within it), `1 + (u - 1) / c` updates: over them what
/// the probe sees of it changes by about its whole share, as `hao_change` weighs a moved occluder by the
/// share it covers. A big occluder near the probe that moves its distance in a few updates leaves it a few,
/// a small one (a ball rolling past) most of the default's (32 updates, 128 frames), whose noise would
/// otherwise outweigh the lag; one that jumped or whose motion is unknown (added, removed; `u` at most 1),
/// the last update alone, as a light that changed does (`CHANGED_HISTORY`). At least 1.
pub fn moved_cap(p: Vec3, spacing: f32, phases: u32, moved: &[MovedVoxels], max_frames: u32) -> u32 {
    let mut cap = max_frames.max(1);
    for m in moved {
        let center = (m.min + m.max) * 0.5;
        let half = (m.max - m.min) * 0.5;
        let r = ((half.x + half.y + half.z) / 3.0).max(1.0e-4);
        let d = ((p - center).abs() - half).max(Vec3::ZERO).length();
        if !(d <= MOVED_REACH_RADII * r + spacing) {
            continue;
        }
        let u = d.max(spacing) / (m.motion.max(1.0e-6) * phases.max(1) as f32);
        let s = r / p.distance(center).max(r);
        let updates = if u <= 1.0 { 1.0 } else { 1.0 + (u - 1.0) / (s * s) };
        cap = cap.min(updates.clamp(1.0, cap as f32) as u32);
    }
    cap
}

/// The irradiance over pi that Bevy's PBR reads from an ambient cube for a surface of unit normal `n`
/// (Valve's formula, as `irradiance_volume.wgsl` applies it): `sum(n_i^2 * face(sign n_i))`.
pub fn ambient_cube(faces: &[Vec3; 6], n: Vec3) -> Vec3 {
    let pick = |axis: usize, positive: bool| faces[axis * 2 + usize::from(!positive)];
    let nn = n * n;
    nn.x * pick(0, n.x >= 0.0) + nn.y * pick(1, n.y >= 0.0) + nn.z * pick(2, n.z >= 0.0)
}

/// The irradiance over pi Bevy's PBR reads from an irradiance volume over the window `window` at the
/// point `p` for the unit normal `n`, as `irradiance_volume.wgsl` samples it: [`sample_faces`], then
/// [`ambient_cube`]. `None` outside the window's [`ProbeWindow::bounds`], where Bevy applies no volume.
pub fn sample_volume(window: &ProbeWindow, faces: impl Fn(UVec3) -> [Vec3; 6], p: Vec3, n: Vec3) -> Option<Vec3> {
    sample_faces(window, faces, p).map(|f| ambient_cube(&f, n))
}

/// The faces Bevy's PBR reads from the volume over `window` at `p` (each face trilinear between the eight
/// probes around `p`, the point clamped half a probe inside the window, as `irradiance_volume.wgsl`
/// samples it; `faces` of a probe by its index in the window), before the ambient cube's weights; `None`
/// outside the window's bounds.
pub fn sample_faces(window: &ProbeWindow, faces: impl Fn(UVec3) -> [Vec3; 6], p: Vec3) -> Option<[Vec3; 6]> {
    let mut e = [Vec3::ZERO; 6];
    for (c, w) in trilinear_probes(window, p)? {
        let probe = faces(c);
        for k in 0..PROBE_FACES.len() {
            e[k] += w * probe[k];
        }
    }
    Some(e)
}

/// The probes Bevy's PBR reads at `p` from the volume over `window` and their trilinear weights (each a
/// probe's index in the window, the point clamped half a probe inside the window, as
/// `irradiance_volume.wgsl` samples it; corners of weight 0 left out), or `None` outside the window's
/// bounds: what [`sample_faces`] and `cpu::lighting::window_faces` weigh.
pub fn trilinear_probes(window: &ProbeWindow, p: Vec3) -> Option<impl Iterator<Item = (UVec3, f32)>> {
    let (lo, hi) = window.bounds();
    if p.cmplt(lo).any() || p.cmpgt(hi).any() {
        return None;
    }
    let r = window.counts.as_vec3();
    let stp = ((p - lo) / (hi - lo) * r).clamp(Vec3::splat(0.5), r - Vec3::splat(0.5)) - Vec3::splat(0.5);
    let base = stp.floor().as_uvec3().min(window.counts - UVec3::ONE);
    let f = stp - base.as_vec3();
    let last = window.counts - UVec3::ONE;
    Some((0..8u32).filter_map(move |corner| {
        let o = UVec3::new(corner & 1, (corner >> 1) & 1, corner >> 2);
        let w = Vec3::select(o.cmpeq(UVec3::ONE), f, Vec3::ONE - f).element_product();
        (w > 0.0).then(|| ((base + o).min(last), w))
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::grid::{VoxelGrid, VoxelOccupancy};
    use crate::cpu::march::VoxelMips;

    /// A lit floor: every occupied voxel of radiance `radiance`, its normal +y.
    struct Floor(Vec3);
    impl LitVoxels for Floor {
        fn voxel(&self, _: usize, _: IVec3) -> (Vec3, Vec3) {
            (self.0, Vec3::Y)
        }
    }

    /// A grid of 0.25 m cells from the origin with a floor layer at y = 2 (0.5-0.75 m), over all of it.
    fn floor() -> (VoxelMips, Vec3) {
        (cells_grid((0..64).flat_map(|x| (0..64).map(move |z| UVec3::new(x, 2, z)))), Vec3::ZERO)
    }

    /// The occupancy pyramid of a grid of 64 x 16 x 64 cells of 0.25 m from the origin with `cells` set.
    fn cells_grid(cells: impl IntoIterator<Item = UVec3>) -> VoxelMips {
        let grid = VoxelGrid::new(Vec3::ZERO, 0.25, UVec3::new(64, 16, 64)).unwrap();
        let occupancy = VoxelOccupancy::new(grid, false);
        for c in cells {
            occupancy.set(c);
        }
        VoxelMips::new(&occupancy, 4)
    }

    #[test]
    fn a_probe_over_a_lit_floor_sees_its_radiance_below_and_nothing_above() {
        let (mips, origin) = floor();
        let levels = [TraceLevel { origin, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        let radiance = Vec3::new(100.0, 50.0, 25.0);
        // 0.35 m over the floor's top, 8 m from its edges: the floor fills the lower half of the sphere but
        // for 2.5 degrees over the horizon.
        let p = Vec3::new(8.0, 1.1, 8.0);
        let faces = gather_probe(&levels, &Floor(radiance), p, 0.25, 4096, Vec2::new(0.3, 0.7));
        // Facing down: E / pi = L.
        let down = faces[3];
        assert!((down / radiance - Vec3::splat(1.0)).abs().max_element() < 0.03, "{down}");
        assert_eq!(faces[2], Vec3::ZERO, "nothing above");
        // Sideways, the cosine-weighted half below the horizon: L / 2, less the band the floor misses at the
        // horizon (2 sin(2.5 deg) / pi of it, 0.028).
        for side in [0, 1, 4, 5] {
            assert!((faces[side] / radiance - Vec3::splat(0.5)).abs().max_element() < 0.04, "{}", faces[side]);
        }
        // Read back along a normal as Bevy does: a floor seen by a surface facing down gets L.
        assert!((ambient_cube(&faces, Vec3::NEG_Y) - down).length() < 1e-3);
    }

    #[test]
    fn a_probe_in_the_floor_moves_out_along_its_normal_and_one_in_free_space_stays() {
        let (mips, origin) = floor();
        let levels = [TraceLevel { origin, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        let inside = Vec3::new(8.0, 0.6, 8.0);
        let moved = relocate_probe(&levels, &Floor(Vec3::ONE), inside, 1.0);
        assert!(
            moved.y >= 0.75 && moved.y <= 0.6 + RELOCATE_MAX + 1e-5 && (moved.x, moved.z) == (inside.x, inside.z),
            "{moved}"
        );
        let free = Vec3::new(8.0, 2.0, 8.0);
        assert_eq!(relocate_probe(&levels, &Floor(Vec3::ONE), free, 1.0), free);
        // Moved out, it sees the floor below as a probe over it does.
        let faces = gather_probe(&levels, &Floor(Vec3::ONE), moved, 0.25, 1024, Vec2::ZERO);
        assert!(faces[3].x > 0.9 && faces[2].x == 0.0, "{faces:?}");
    }

    #[test]
    fn a_probe_in_a_rooms_corner_moves_into_the_room_even_where_its_own_voxel_points_into_the_floor() {
        // A floor (cell y = 2, for x <= 32) and a wall on it (cell x = 32, y >= 3), the room on the -x side.
        let mips = cells_grid((0..64).flat_map(|z| {
            (0..=32).map(move |x| UVec3::new(x, 2, z)).chain((3..16).map(move |y| UVec3::new(32, y, z)))
        }));
        let levels = [TraceLevel { origin: Vec3::ZERO, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        // The joint's voxels (x = 32, y = 2): the wall's bottom face and the floor's top cancel, and what is
        // left (the floor's underside, say) points down, out of the room. The floor faces up, the wall -x.
        struct Corner;
        impl LitVoxels for Corner {
            fn voxel(&self, _: usize, c: IVec3) -> (Vec3, Vec3) {
                let normal = match (c.x, c.y) {
                    (32, 2) => Vec3::new(0.1, -0.6, 0.0),
                    (_, 2) => Vec3::Y,
                    _ => Vec3::NEG_X,
                };
                (Vec3::ONE, normal)
            }
        }
        let joint = Vec3::new(8.125, 0.625, 8.125);
        let n = neighbourhood_normal(&levels, &Corner, 0, IVec3::new(32, 2, 32));
        assert!(n.x < -0.2 && n.y > 0.0 && n.z.abs() < 1e-6, "{n}");
        // It ends in the room: over the floor, on the wall's room side.
        let moved = relocate_probe(&levels, &Corner, joint, 1.0);
        assert!(moved.x < 8.0 && moved.y >= 0.75 && !occupied_at(&levels[0], moved), "{moved}");
        // By its own voxel's normal alone it would have gone down through the floor, out of the room.
        let own = Corner.voxel(0, IVec3::new(32, 2, 32)).1.normalize();
        assert!(!occupied_at(&levels[0], joint + own * 0.25) && (joint + own * 0.25).y < 0.5);
    }

    #[test]
    fn the_probes_fade_out_toward_the_windows_edges_without_a_step_as_it_moves() {
        let counts = UVec3::new(48, 24, 48);
        let mut last: Option<Vec<f32>> = None;
        // The focus across a whole lattice cell and into the next, in steps of a twentieth of a spacing.
        for k in 0..=30 {
            let focus = Vec3::new(3.0 + 0.025 * k as f32, 1.7, -2.2);
            let w = probe_window(focus, 0.5, counts).unwrap();
            let weights: Vec<f32> = (0..w.len()).map(|i| w.edge_fade(w.lattice(i))).collect();
            // The outermost probes of every axis hold nothing; those near the focus all of it.
            for i in 0..w.len() {
                let c = (w.lattice(i) - w.min).as_uvec3();
                let outer = c.cmpeq(UVec3::ZERO).any() || c.cmpeq(counts - UVec3::ONE).any();
                assert!(!outer || weights[i as usize] == 0.0, "{c} {}", weights[i as usize]);
                let near = (w.position(w.lattice(i)) - focus).abs().cmplt(Vec3::new(10.0, 4.0, 10.0)).all();
                assert!(!near || weights[i as usize] == 1.0, "{c} {}", weights[i as usize]);
            }
            // A lattice point's weight moves by a twentieth of a spacing's share of the fade, not by a step,
            // also where the window scrolls by a probe.
            if let Some(last) = &last {
                let prev = probe_window(focus - Vec3::new(0.025, 0.0, 0.0), 0.5, counts).unwrap();
                for i in 0..w.len() {
                    let q = w.lattice(i);
                    let before =
                        if (q - prev.min).cmpge(IVec3::ZERO).all() && (q - prev.min).cmplt(counts.as_ivec3()).all() {
                            prev.edge_fade(q)
                        } else {
                            0.0
                        };
                    assert!((weights[i as usize] - before).abs() <= 0.05 / EDGE_FADE_SPACINGS + 1e-5);
                }
                assert_eq!(last.len(), weights.len());
            }
            last = Some(weights);
        }
        // An axis of fewer than 4 probes does not fade.
        let flat = probe_window(Vec3::ZERO, 1.0, UVec3::new(8, 2, 8)).unwrap();
        assert_eq!(flat.edge_fade(IVec3::ZERO), 1.0);
    }

    #[test]
    fn the_window_follows_the_focus_and_a_probe_keeps_its_slot() {
        let w = probe_window(Vec3::new(10.2, -3.9, 0.1), 0.5, UVec3::new(8, 4, 8)).unwrap();
        assert_eq!(w.min, IVec3::new(20 - 4, -8 - 2, -4));
        assert_eq!(w.lattice(0), w.min);
        assert_eq!(w.lattice(w.len() - 1), w.min + IVec3::new(7, 3, 7));
        let (lo, hi) = w.bounds();
        assert_eq!(lo, (w.min.as_vec3() - 0.5) * 0.5);
        assert_eq!(hi - lo, Vec3::new(4.0, 2.0, 4.0));
        // Scrolled by one probe along x, the probes both windows hold keep their slots, and every slot is
        // used once.
        let moved = probe_window(Vec3::new(10.7, -3.9, 0.1), 0.5, UVec3::new(8, 4, 8)).unwrap();
        assert_eq!(moved.min, w.min + IVec3::X);
        let q = w.min + IVec3::new(3, 1, 2);
        assert_eq!(w.slot(q), moved.slot(q));
        let mut slots: Vec<u32> = (0..moved.len()).map(|i| moved.slot(moved.lattice(i))).collect();
        slots.sort_unstable();
        assert_eq!(slots, (0..moved.len()).collect::<Vec<_>>());
        assert_eq!(probe_window(Vec3::NAN, 0.5, UVec3::splat(4)), None);
        assert_eq!(probe_window(Vec3::splat(1.0e12), 0.5, UVec3::splat(4)), None);
        assert_eq!(probe_window(Vec3::ZERO, 0.0, UVec3::splat(4)), None);
    }

    #[test]
    fn rays_cover_the_sphere_and_the_history_is_a_mean_then_a_window() {
        // The directions' mean is near zero and each a unit vector, for any rotation.
        for rotation in [Vec2::ZERO, probe_rotation(7, 3), probe_rotation(1000, 99)] {
            let dirs: Vec<Vec3> = (0..256).map(|k| sphere_direction(k, 256, rotation)).collect();
            assert!(dirs.iter().all(|d| (d.length() - 1.0).abs() < 1e-5));
            assert!((dirs.iter().copied().sum::<Vec3>() / 256.0).length() < 0.02);
        }
        let r = probe_rotation(3, 5);
        assert!(r.cmpge(Vec2::ZERO).all() && r.cmplt(Vec2::ONE).all() && r != probe_rotation(3, 6));
        // A mean of the first updates, then a window of max_frames.
        let one = [Vec3::ONE; 6];
        let (h, n) = blend_probe([Vec3::ZERO; 6], 0, one, 4);
        assert_eq!((h, n), (one, 1));
        let (h, n) = blend_probe(h, n, [Vec3::ZERO; 6], 4);
        assert_eq!((h[0], n), (Vec3::splat(0.5), 2));
        let (h, n) = blend_probe(h, 4, one, 4);
        assert_eq!((h[0], n), (Vec3::splat(0.625), 4));
    }

    #[test]
    fn probes_near_a_moved_occluder_keep_the_history_its_motion_allows() {
        // A 1 m box sliding 1 cm a frame, listed with the box around it now and last frame; probes 0.5 m
        // apart, each updated every fourth frame, 32 updates elsewhere.
        let moved = [MovedVoxels { min: Vec3::new(-0.5, 0.0, -0.5), max: Vec3::new(0.51, 1.0, 0.5), motion: 0.01 }];
        let cap = |x: f32, motion: f32| {
            let m = [MovedVoxels { motion, ..moved[0] }];
            moved_cap(Vec3::new(x, 0.5, 0.0), 0.5, 4, &m, 32)
        };
        // Inside it, where it covers the whole view: the updates it takes to cross a spacing (50 frames, 12.5
        // updates); at 5 cm a frame, 2.5.
        assert_eq!((cap(0.0, 0.01), cap(0.5, 0.01), cap(0.0, 0.05)), (12, 12, 2));
        // Outside, the share of the view it covers stretches them: 0.39 m from its side (0.9 m from its
        // centre, a third of the view), 1 + 1.5 / 0.31; farther, 1 + 3.1 / 0.14; at 1 cm a frame, already
        // the default's.
        assert_eq!((cap(0.9, 0.05), cap(1.335, 0.05), cap(0.9, 0.01)), (5, 22, 32));
        // Past the reach (2 mean half-extents past a spacing, 1.5 m from the box) the cap is the default's.
        assert_eq!((cap(2.0, 0.1), cap(2.02, 100.0)), (32, 32));
        // A jump (farther in an update than from the probe), an unknown motion (`UNKNOWN_MOTION`), or the
        // box everywhere: the last update alone.
        assert_eq!((cap(0.9, 0.1), cap(0.0, 3.0), cap(1.5, 1.0e30)), (1, 1, 1));
        let everywhere = [MovedVoxels { min: Vec3::splat(-1.0e30), max: Vec3::splat(1.0e30), motion: 1.0e30 }];
        assert_eq!(moved_cap(Vec3::new(1.0e4, 3.0, -7.0), 0.5, 4, &everywhere, 32), 1);
        // A box of no size still counts (as a point of 0.1 mm), moved by 1 m a frame: a jump.
        let point = [MovedVoxels { min: Vec3::ZERO, max: Vec3::ZERO, motion: 1.0 }];
        assert_eq!(moved_cap(Vec3::new(0.3, 0.0, 0.0), 0.5, 4, &point, 32), 1);
        // Nothing moved, or a probe far off: the cap as given, at least 1; a motion of 0 or NaN takes none.
        assert_eq!((moved_cap(Vec3::ZERO, 0.5, 4, &[], 32), moved_cap(Vec3::ZERO, 0.5, 4, &[], 0)), (32, 1));
        assert_eq!(moved_cap(Vec3::new(9.0, 0.0, 0.0), 0.5, 4, &moved, 32), 32);
        assert_eq!((cap(0.0, 0.0), cap(0.0, f32::NAN)), (32, 32));
        // Blended with the cap, a history that held 32 updates holds the cap's from the next.
        let (_, n) = blend_probe([Vec3::ONE; 6], 32, [Vec3::ZERO; 6], cap(0.0, 0.01));
        assert_eq!(n, 12);
    }

    #[test]
    fn the_volume_is_sampled_as_bevy_samples_it() {
        let window =
            ProbeWindow { min: IVec3::new(-2, 0, -2), counts: UVec3::new(4, 2, 4), spacing: 1.0, focus: Vec3::ZERO };
        // Each probe's +y face its x index, the rest 0.
        let faces = |w: UVec3| std::array::from_fn(|k| if k == 2 { Vec3::splat(w.x as f32) } else { Vec3::ZERO });
        // On a probe: its value; between two along x: the mean; past the last probe, clamped to it; outside
        // the bounds: none; facing down: the -y faces (0).
        let at = |x: f32| sample_volume(&window, faces, Vec3::new(x, 0.0, 0.0), Vec3::Y).unwrap().x;
        assert!((at(0.0) - 2.0).abs() < 1e-5 && (at(0.5) - 2.5).abs() < 1e-5);
        assert!((at(1.4) - 3.0).abs() < 1e-5, "{}", at(1.4));
        assert_eq!(sample_volume(&window, faces, Vec3::new(1.6, 0.0, 0.0), Vec3::Y), None);
        assert_eq!(sample_volume(&window, faces, Vec3::ZERO, Vec3::NEG_Y), Some(Vec3::ZERO));
        // At 45 degrees, half of the +y face.
        let tilted = sample_volume(&window, faces, Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0).normalize()).unwrap();
        assert!((tilted.x - 1.0).abs() < 1e-5);
    }

    #[test]
    fn a_face_gathers_where_the_surfaces_that_read_it_are() {
        // A wall one cell thick (x = 8) across the grid, lit on its +x side only.
        let mips = cells_grid((0..16).flat_map(|y| (0..64).map(move |z| UVec3::new(32, y, z))));
        let levels = [TraceLevel { origin: Vec3::ZERO, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        struct LitSide;
        impl LitVoxels for LitSide {
            fn voxel(&self, _: usize, _: IVec3) -> (Vec3, Vec3) {
                (Vec3::ONE, Vec3::X)
            }
        }
        // A probe 0.2 m on the lit side: its -x face looks at the wall's lit side, which the surfaces facing
        // -x within a spacing (the wall's back, in the other room) do not see; it gathers from past the wall.
        let p = Vec3::new(8.45, 2.0, 8.0);
        let behind = face_origin(&levels, &LitSide, p, Vec3::NEG_X, 0.5);
        assert!(behind.x < 8.0 && behind.x > 7.5 && (behind.y, behind.z) == (p.y, p.z), "{behind}");
        assert_eq!(face_origin(&levels, &LitSide, p, Vec3::NEG_X, 0.1), p, "the wall beyond a spacing of 0.1");
        // Its +x face is read by the wall's lit side, which faces +x 0.2 m behind it: gathered half a cell in
        // front of the wall, where that side is. Nothing within a spacing ahead of it either way.
        let front = face_origin(&levels, &LitSide, p, Vec3::X, 0.5);
        assert!((front - Vec3::new(8.375, 2.0, 8.0)).abs().max_element() < 1e-3, "{front}");
        assert_eq!(face_origin(&levels, &LitSide, p, Vec3::X, 0.1), p, "the wall beyond a spacing of 0.1");
        // A wall whose voxels face the other way (the probe sees its back) reads no +x face there.
        struct BackSide;
        impl LitVoxels for BackSide {
            fn voxel(&self, _: usize, _: IVec3) -> (Vec3, Vec3) {
                (Vec3::ONE, Vec3::NEG_X)
            }
        }
        assert_eq!(face_origin(&levels, &BackSide, p, Vec3::X, 0.5), p, "behind it, the back of a wall");
        let faces = gather_probe(&levels, &LitSide, p, 0.5, 1024, Vec2::ZERO);
        assert_eq!(faces[1], Vec3::ZERO, "the -x face sees the other room: no light");
        // Gathered from the probe itself, the -x face would see the lit side: L (a wall filling the
        // hemisphere but at its rim).
        let from_here = gather_probe(&levels, &LitSide, p, 0.01, 1024, Vec2::ZERO);
        assert!(from_here[1].x > 0.9, "{from_here:?}");
    }
}
