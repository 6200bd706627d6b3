//! The CPU twin of the trace's depth contacts (`src/ao/hao_trace.wgsl`: `depth_contact`, `behind_depth`).
//!
//! The voxel march starts each ray `start_offset` cells off the surface and as many along its way, so that a
//! surface does not occlude itself through the staircase of its own voxels; what lies closer (a moulding on
//! a wall, a floor meeting a pillar, a layer lying on a surface) no voxel of that size can tell from the
//! surface itself. Those first cells of each ray are traced in the depth prepass instead: a few points along
//! the ray are projected into the view, and a point that lies behind the surface the view shows there, by
//! less than a cell, is inside an occluder. The first such point stops the ray (the march is not run).
//! The depth prepass holds every surface the view sees up close, which is where these contacts are: unlike
//! screen-space AO over the whole hemisphere, the rays reach only two cells, so what the view cannot see
//! (behind, off screen) is left to the voxels.
//!
//! The depth prepass also tells where space is free: a point the view shows in front of every surface around
//! it lies in empty space. An occupied voxel blocks every ray that crosses it though the surface in it may
//! cover only part of it, most of all in the coarse levels; a ray that crosses such a cell where the view
//! shows empty space passes on ([`ViewDepth::shows_free_space`], `TraceSettings::depth_free_space`).

use super::ao::{GOLDEN, interleaved_gradient_noise};
use super::march::TraceLevel;
use glam::{IVec2, Mat4, UVec2, Vec2, Vec3, Vec4};

/// Points each ray samples in the depth prepass by default (`TraceSettings::contact_samples`; the presets'
/// choice: `HybridAmbientOcclusion::contact_samples`), evenly along its first cells, shifted by the ray's
/// jitter.
pub const CONTACT_SAMPLES: u32 = 4;
/// How far along the ray the depth prepass is sampled, in cells of the level the ray starts in, per cell of
/// `start_offset` (WGSL: `CONTACT_LENGTH`): the march starts a cell off the surface and a cell along the ray,
/// at 1.4-2 cells from the surface point.
pub const CONTACT_LENGTH: f32 = 2.0;
/// How far behind the surface the view shows a point may lie and still be inside it, in cells (WGSL:
/// `CONTACT_THICKNESS`): deeper, it is behind a surface in front of it (which a screen-space test cannot
/// tell from a solid), and the ray goes on.
pub const CONTACT_THICKNESS: f32 = 1.0;
/// The thickness is measured along the normal of the surface the view shows (WGSL: `CONTACT_GRAZING_COS`):
/// along the view it is [`CONTACT_THICKNESS`] over the cosine between the view and that normal, that cosine
/// taken at least this (at most four cells along the view). Near a silhouette the view grazes the surface,
/// and a point a hair inside it (the floor's contact under a resting sphere, seen from above) lies many
/// cells behind it along the view: measured along the view alone, those contacts were missed, and the floor
/// right under a sphere's silhouette came out lighter than a hand's breadth further out. Such a point counts
/// only where its voxel is occupied ([`depth_contact`]): behind a bar seen edge on, it lies in the open.
pub const CONTACT_GRAZING_COS: f32 = 0.25;
/// How far the sampled points are lifted off the surface along its normal, in pixels of the view at the
/// surface (WGSL: `CONTACT_LIFT_PIXELS`; [`ViewDepth::pixel_size`]), at most [`CONTACT_LIFT_CELLS`]: against
/// the depth of a pixel's neighbours, which a grazing view or a curved surface sets a little in front of the
/// ray's first points, and which would otherwise occlude the surface by itself. That error is the depth
/// prepass's, so the lift is in its pixels: a lift of an eighth of a cell alone (before) hid the contacts of
/// layers and mouldings lying on a surface at 1920x1080, where it is 2-3 pixels (docs/figures.md).
pub const CONTACT_LIFT_PIXELS: f32 = 0.5;
/// The most the sampled points are lifted, in cells of the level the ray starts in (WGSL:
/// `CONTACT_LIFT_CELLS`): where a pixel is larger than a quarter of a cell (a small object seen whole, a low
/// resolution), half a pixel would lift the points over what lies within the first cell, which only the
/// contacts can find.
pub const CONTACT_LIFT_CELLS: f32 = 0.125;
/// A point is behind the view's surface only if its view depth exceeds the surface's by more than this share
/// (WGSL: `CONTACT_DEPTH_EPSILON`): the depth prepass's precision.
pub const CONTACT_DEPTH_EPSILON: f32 = 1.0e-3;

/// How a point lies behind the surface the view shows at its pixel ([`ViewDepth::behind_clip`]; WGSL: the
/// codes `behind_depth` returns, 0, 1 and 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Behind {
    /// In front of it or too deep, off the view, behind the camera or over the background.
    No,
    /// Behind it by less than the thickness along the view.
    AlongView,
    /// Deeper along the view, but within the thickness along the surface's normal (asked only with the
    /// direction the view looks along).
    AlongNormal,
}

/// The view's depth prepass as the trace reads it (WGSL: `depth_texture` and `view`'s matrices).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewDepth {
    /// The view's size in pixels.
    pub size: UVec2,
    /// The prepass's depth (normalized device coordinates, Bevy's reverse Z: 0 is the background), row by
    /// row.
    pub depth: Vec<f32>,
    /// World to clip space (with the view's TAA jitter, as the prepass was drawn).
    pub clip_from_world: Mat4,
    /// World to view space.
    pub view_from_world: Mat4,
    /// Clip to view space.
    pub view_from_clip: Mat4,
    /// The normal prepass's world normals (unit; zero for the background), row by row, as the trace decodes
    /// them.
    pub normals: Vec<Vec3>,
}

/// How far in front of the surfaces the view shows around it a voxel hit must lie to be passed as free
/// space, in cells of the hit's level (WGSL: `FREE_SPACE_MARGIN`): the surface in the hit cell may lie
/// anywhere in it, in front of the point the trace takes for it.
pub const FREE_SPACE_MARGIN: f32 = 1.0;
/// How many voxel hits in free space a ray passes at most (WGSL: `MAX_FREE_SPACE_PASSES`); the next one
/// occludes. Each pass restarts the march past the cell with the full `steps` budget. A GPU warp runs each
/// pass after its slowest lane's march before it, so each costs the warp a march; against the ray-traced
/// reference (`High`) 1, 2 and 4 passes gave 0.0234, 0.0225 and 0.0222 on the built-in cathedral, and 0.0295,
/// 0.0249 and 0.0216 on `builtin:apartment`, for 12, 20 and 25 % (17, 32 and 48 %) more texel visits a ray
/// as a warp pays them (docs/figures.md).
pub const MAX_FREE_SPACE_PASSES: u32 = 2;

/// How near the surface a voxel hit must be, in cells of the level the ray starts in, for the trace to test
/// it against the view's depth whatever the preset (WGSL: `NEAR_FREE_SPACE_CELLS`). An occupied voxel
/// blocks every ray that crosses it though its surface may lie up to a cell away: near a crease or a
/// contact (a floor beside a wall, under a resting ball) the rays that leave the surface along the other
/// surface, or past the ball, cross its voxels in their first cells and darken the surface as if the other
/// one were a cell nearer. Against the ray-traced reference (`ao_compare --bias`, the CPU twin) passing the
/// near hits the view shows in free space lowered the error where the reference AO is under 0.5 from 0.123
/// to 0.043 on the `contacts` room, and the error over the view on every scene measured
/// (docs/figures.md, *Contacts*).
pub const NEAR_FREE_SPACE_CELLS: f32 = 8.0;
/// How far in front of the surfaces the view shows around it a near voxel hit must lie to be passed, in the
/// view's pixels at the hit (WGSL: `NEAR_FREE_SPACE_PIXELS`): a point that far in front of the nearest
/// surface the 3x3 pixels show is empty, up to the depth's own error across a pixel.
pub const NEAR_FREE_SPACE_PIXELS: f32 = 1.0;
/// How many near voxel hits in free space a ray passes at most (WGSL: `MAX_NEAR_FREE_SPACE_PASSES`). Unlike
/// [`MAX_FREE_SPACE_PASSES`], the march goes on with the steps it has left, so a ray visits no more texels
/// than without the passes.
pub const MAX_NEAR_FREE_SPACE_PASSES: u32 = 8;

impl ViewDepth {
    /// Whether the view shows the world point `p` in free space (WGSL: `shows_free_space`): on the view, and
    /// in front of the nearest surface of the 3x3 pixels around the one it projects to by more than
    /// `margin` (world units, in view depth), or with none of them showing a surface (the background).
    /// Points off the view or behind the camera are not: the view cannot tell. The nearest of nine rather
    /// than one pixel keeps a point beside a silhouette from counting as free where the surface is a pixel
    /// away.
    pub fn shows_free_space(&self, p: Vec3, margin: f32, depth_loads: &mut u64) -> bool {
        let Some(pixel) = self.pixel_at(self.clip_from_world * p.extend(1.0)) else { return false };
        // The nearest surface around it: the largest depth (reverse Z), 0 where none shows one.
        let mut nearest = 0.0f32;
        for k in 0..9 {
            let q = pixel.as_ivec2() + IVec2::new(k % 3 - 1, k / 3 - 1);
            if q.cmplt(IVec2::ZERO).any() || q.cmpge(self.size.as_ivec2()).any() {
                continue;
            }
            *depth_loads += 1;
            nearest = nearest.max(self.depth_at(q));
        }
        if nearest <= 0.0 {
            return true;
        }
        -(self.view_from_world * p.extend(1.0)).z < self.surface_view_depth(nearest) - margin
    }

    /// Whether the world point `p` lies behind the surface the view shows at the pixel it projects to, by
    /// more than [`CONTACT_DEPTH_EPSILON`] of its depth and less than `thickness` (world units) along the
    /// view, or with `grazing` along that surface's normal ([`CONTACT_GRAZING_COS`]), counting the prepass
    /// samples it reads in `depth_loads`. Points off the view, behind the camera or over the background are
    /// not.
    pub fn behind(&self, p: Vec3, thickness: f32, grazing: bool, depth_loads: &mut u64) -> bool {
        let depth = -(self.view_from_world * p.extend(1.0)).z;
        let eye = grazing.then(|| self.eye_direction(p));
        self.behind_clip(self.clip_from_world * p.extend(1.0), depth, thickness, eye, depth_loads) != Behind::No
    }

    /// How far the world point `p` lies behind the surface the view shows at the pixel it projects to, in
    /// view depth (world units; negative in front of it), or `None` off the view, behind the camera or over
    /// the background: what [`ViewDepth::behind`] tests, for the lab's accounting of the contacts it misses.
    pub fn depth_behind(&self, p: Vec3) -> Option<f32> {
        let pixel = self.pixel_at(self.clip_from_world * p.extend(1.0))?;
        let d = self.depth_at(pixel.as_ivec2());
        (d > 0.0).then(|| -(self.view_from_world * p.extend(1.0)).z - self.surface_view_depth(d))
    }

    /// The direction the view looks along at the world point `p` (WGSL: `eye_direction` in `trace`): from
    /// the near plane's point at its pixel position to it, for a perspective or an orthographic view alike.
    /// The GPU maps the near plane's point to world space with the view's `world_from_clip`; here it is found
    /// in view space with `view_from_clip` and turned to world space by the view's rotation (a view matrix is
    /// rigid), which spares the twin a matrix inverse per call.
    pub fn eye_direction(&self, p: Vec3) -> Vec3 {
        let clip = self.clip_from_world * p.extend(1.0);
        let near = self.view_from_clip.project_point3((clip.truncate() / clip.w).truncate().extend(1.0));
        let along = self.view_from_world.transform_point3(p) - near;
        (glam::Mat3::from_mat4(self.view_from_world).transpose() * along).normalize_or_zero()
    }

    /// How a point given in clip space and by its view depth lies behind the surface the view shows
    /// ([`ViewDepth::behind`]; WGSL: `behind_depth`): both are linear along a ray, so a ray's points cost a
    /// multiply-add each. With `eye`, the direction the view looks along ([`ViewDepth::eye_direction`]), a
    /// point deeper than `thickness` along the view may still be within it along the surface's normal, which
    /// is read only then.
    pub fn behind_clip(
        &self,
        clip: Vec4,
        depth: f32,
        thickness: f32,
        eye: Option<Vec3>,
        depth_loads: &mut u64,
    ) -> Behind {
        let Some(pixel) = self.pixel_at(clip) else { return Behind::No };
        *depth_loads += 1;
        let d = self.depth_at(pixel.as_ivec2());
        if d <= 0.0 {
            return Behind::No;
        }
        let surface = self.surface_view_depth(d);
        if !(depth > surface * (1.0 + CONTACT_DEPTH_EPSILON)) {
            return Behind::No;
        }
        if depth < surface + thickness {
            return Behind::AlongView;
        }
        let Some(eye) = eye else { return Behind::No };
        *depth_loads += 1;
        let n = self.normal_at(pixel.as_ivec2());
        if depth < surface + thickness / n.dot(eye).abs().max(CONTACT_GRAZING_COS) {
            Behind::AlongNormal
        } else {
            Behind::No
        }
    }

    /// The normal prepass's normal at pixel `p`: zero off the view or where the normals are shorter than
    /// the view.
    fn normal_at(&self, p: IVec2) -> Vec3 {
        if p.x < 0 || p.y < 0 || p.x >= self.size.x as i32 || p.y >= self.size.y as i32 {
            return Vec3::ZERO;
        }
        self.normals.get((p.y as u32 * self.size.x + p.x as u32) as usize).copied().unwrap_or(Vec3::ZERO)
    }

    /// The size of one of the view's pixels, in world units, at a point whose clip-space w is `clip_w`
    /// (WGSL: `pixel_size`): the view-space height of a pixel's step in normalized device coordinates,
    /// for a perspective (w: the view depth) or an orthographic projection (w: 1) alike.
    pub fn pixel_size(&self, clip_w: f32) -> f32 {
        2.0 * clip_w * self.view_from_clip.y_axis.y.abs() / self.size.y.max(1) as f32
    }

    /// The pixel a point at `clip` (clip space) projects to, or `None` off the view or behind the camera
    /// (WGSL: the projection in `behind_depth` and `shows_free_space`).
    fn pixel_at(&self, clip: Vec4) -> Option<UVec2> {
        // Also a NaN w; a view without pixels (which the GPU never traces) shows nothing.
        if !(clip.w > 0.0) || self.size.min_element() == 0 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        if ndc.x.abs() > 1.0 || ndc.y.abs() > 1.0 || ndc.z <= 0.0 || ndc.z > 1.0 {
            return None;
        }
        let size = self.size.as_vec2();
        Some((Vec2::new(ndc.x + 1.0, 1.0 - ndc.y) * 0.5 * size).as_uvec2().min(self.size - UVec2::ONE))
    }

    /// The prepass's depth at pixel `p`: 0 (the background) off the view or where the depth is shorter
    /// than the view.
    fn depth_at(&self, p: IVec2) -> f32 {
        if p.x < 0 || p.y < 0 || p.x >= self.size.x as i32 || p.y >= self.size.y as i32 {
            return 0.0;
        }
        self.depth.get((p.y as u32 * self.size.x + p.x as u32) as usize).copied().unwrap_or(0.0)
    }

    /// The view depth of the surface at prepass depth `d` (WGSL: `surface_view_depth`): the z and w rows of
    /// view_from_clip times (0, 0, d, 1).
    fn surface_view_depth(&self, d: f32) -> f32 {
        let m = &self.view_from_clip;
        -(m.z_axis.z * d + m.w_axis.z) / (m.z_axis.w * d + m.w_axis.w)
    }
}

/// The jitter of a pixel's contact samples in frame `frame` (WGSL: `contact_jitter`), in `[0, 1)`: its own
/// interleaved gradient noise ([`ray_jitter`] shifts it from one ray to the next).
pub fn contact_jitter(pixel: Vec2, frame: u32) -> f32 {
    interleaved_gradient_noise(Vec2::new(pixel.y, pixel.x) + Vec2::new(43.0, 11.0), frame)
}

/// The jitter of ray `i` of a pixel whose [`contact_jitter`] is `pixel_jitter` (WGSL: in `trace`): shifted by
/// `i` times the golden ratio.
pub fn ray_jitter(pixel_jitter: f32, i: u32) -> f32 {
    (pixel_jitter + i as f32 * GOLDEN).fract()
}

/// How far a ray's contact points are lifted off the surface (WGSL: `contact_lift`): [`CONTACT_LIFT_PIXELS`]
/// pixels of size `pixel`, at most [`CONTACT_LIFT_CELLS`] cells of size `cell` (world units alike).
pub fn contact_lift(pixel: f32, cell: f32) -> f32 {
    (CONTACT_LIFT_PIXELS * pixel).min(CONTACT_LIFT_CELLS * cell)
}

/// The distance from the surface point `world` (normal `normal`) along ray `dir` to its first contact in the
/// depth prepass within `length` (world units), or `None` (WGSL: `depth_contact`): `samples` points at
/// `length * (k + jitter) / samples`, lifted [`contact_lift`] along the normal, the first that
/// is [`ViewDepth::behind`] the view's surface by less than [`CONTACT_THICKNESS`] cells. With `grazing` (where
/// the view hides the march's start, [`super::near`]: the level the ray starts in), also one within that
/// thickness along that surface's normal that lies in an occupied cell of the level's finest occupancy: a
/// surface the view grazes reaches that deep only where its voxels do (a thin bar seen edge on does not).
/// `cell` is the cell size of the level the ray starts in.
#[allow(clippy::too_many_arguments)]
pub fn depth_contact(
    view: &ViewDepth,
    world: Vec3,
    normal: Vec3,
    dir: Vec3,
    cell: f32,
    length: f32,
    samples: u32,
    jitter: f32,
    grazing: Option<&TraceLevel>,
    depth_loads: &mut u64,
) -> Option<f32> {
    let lift = contact_lift(view.pixel_size((view.clip_from_world * world.extend(1.0)).w), cell);
    let eye = grazing.map(|_| view.eye_direction(world));
    let base = (world + normal * lift).extend(1.0);
    // The ray's start and direction in clip space and in view depth: each point is a multiply-add away.
    let (clip, clip_dir) = (view.clip_from_world * base, view.clip_from_world * dir.extend(0.0));
    let (depth, depth_dir) = (-(view.view_from_world * base).z, -(view.view_from_world * dir.extend(0.0)).z);
    (0..samples).map(|k| length * (k as f32 + jitter) / samples as f32).find(|&t| {
        match view.behind_clip(clip + clip_dir * t, depth + depth_dir * t, CONTACT_THICKNESS * cell, eye, depth_loads) {
            Behind::No => false,
            Behind::AlongView => true,
            Behind::AlongNormal => grazing.is_some_and(|level| {
                level.mips.occupied(level.level_position(base.truncate() + dir * t).floor().as_ivec3())
            }),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A view looking down -Z from z = 10 at a floor at z = 0, with a step (0.25 high over x > 0): the
    /// prepass's depth of every pixel, as the GPU would draw it.
    fn floor_with_a_step() -> ViewDepth {
        let size = UVec2::new(64, 64);
        let clip_from_view = Mat4::perspective_infinite_reverse_rh(1.0, 1.0, 0.1);
        let view_from_world = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y);
        let clip_from_world = clip_from_view * view_from_world;
        let world_from_clip = clip_from_world.inverse();
        let mut depth = Vec::new();
        for y in 0..size.y {
            for x in 0..size.x {
                let ndc = Vec2::new((x as f32 + 0.5) / 32.0 - 1.0, 1.0 - (y as f32 + 0.5) / 32.0);
                let near = world_from_clip.project_point3(ndc.extend(1.0));
                let far = world_from_clip.project_point3(ndc.extend(1.0e-4));
                let dir = (far - near).normalize();
                // The ray from the camera to the floor or the step's top.
                let top = if near.x + dir.x * (near.z - 0.25) / -dir.z > 0.0 { 0.25 } else { 0.0 };
                let hit = near + dir * ((near.z - top) / -dir.z);
                depth.push(clip_from_world.project_point3(hit).z);
            }
        }
        let normals = depth.iter().map(|_| Vec3::Z).collect();
        ViewDepth { size, depth, clip_from_world, view_from_world, view_from_clip: clip_from_view.inverse(), normals }
    }

    /// The voxel hits near the surface that the view shows in empty space are passed (`depth_contacts`):
    /// over [`floor_with_a_step`]'s view, voxels the view does not show (a block of them over the floor at
    /// y < -2, as a neighbour's voxels a cell fatter than it would be) and the step's voxels a cell above its
    /// top. A ray from the floor into the block passes; one whose lifted march crosses the step's fat layer
    /// but which from the floor meets the step's side, and one into that side, stop there; without the view
    /// all three stop.
    #[test]
    fn near_voxel_hits_the_view_shows_in_empty_space_are_passed() {
        use crate::cpu::ao::{TraceSettings, TraceWork, voxel_ray_occluder};
        use crate::cpu::grid::{VoxelGrid, VoxelOccupancy};
        use crate::cpu::march::{TraceLevel, VoxelMips};
        use glam::{IVec3, UVec3};
        let view = floor_with_a_step();
        let grid = VoxelGrid::new(Vec3::new(-4.0, -4.0, -0.5), 0.25, UVec3::new(32, 32, 16)).unwrap();
        let occupancy = VoxelOccupancy::new(grid, false);
        for i in 0..32 {
            for j in 0..32 {
                // The floor's layer under z = 0, and the step (x > 0, its top at z = 0.25) a layer fatter.
                occupancy.set(UVec3::new(i, j, 1));
                if i >= 16 {
                    occupancy.set(UVec3::new(i, j, 2));
                    occupancy.set(UVec3::new(i, j, 3));
                }
            }
        }
        // The block over the floor: x in [-0.5, -0.25], z in [0.25, 0.75], y < -2.
        for j in 0..8 {
            occupancy.set(UVec3::new(14, j, 3));
            occupancy.set(UVec3::new(14, j, 4));
        }
        let mips = VoxelMips::new(&occupancy, 4);
        let levels = [TraceLevel { origin: grid.origin, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        let settings = |start_offset: f32| TraceSettings {
            rays: 1,
            steps: 64,
            max_distance: 3.0,
            falloff: 1.0,
            intensity: 1.0,
            start_offset,
            ignore_back_hits: false,
            depth_contacts: true,
            depth_free_space: false,
            contact_samples: CONTACT_SAMPLES,
        };
        let cases = [
            ("into the block", Vec3::new(-0.1, -3.0, 0.0), Vec3::new(-0.8, 0.0, 0.6), 1.0, false),
            // The ray lifted a cell crosses the step's fat layer over its top; the floor's own ray meets the
            // step's side (at x = 0, z = 0.15): the hit is judged on the floor's ray, and stops it.
            ("toward the step's top", Vec3::new(-0.3, 0.0, 0.0), Vec3::new(0.9, 0.0, 0.436), 1.0, true),
            ("into the step's side", Vec3::new(-0.3, 0.0, 0.0), Vec3::new(0.95, 0.0, 0.3122), 0.25, true),
        ];
        let mut work = TraceWork::default();
        for (what, world, dir, start_offset, stops) in cases {
            let s = settings(start_offset);
            let without = voxel_ray_occluder(&levels, None, world, Vec3::Z, dir.normalize(), 0, &s, &mut work);
            assert!(without.is_some(), "{what}: the voxels alone stop it");
            let with = voxel_ray_occluder(&levels, Some(&view), world, Vec3::Z, dir.normalize(), 0, &s, &mut work);
            assert_eq!(with.is_some(), stops, "{what}: {with:?}");
        }
        assert_eq!(work.near_free_space_passes, 1, "{work:?}");
        // Without depth contacts the view passes nothing here (`depth_free_space` is off).
        let s = TraceSettings { depth_contacts: false, ..settings(1.0) };
        let (world, dir) = (cases[0].1, cases[0].2.normalize());
        assert!(voxel_ray_occluder(&levels, Some(&view), world, Vec3::Z, dir, 0, &s, &mut work).is_some());
    }

    #[test]
    fn the_view_looks_from_its_camera_or_along_its_axis() {
        // Perspective, the camera at (0, 0, 10): from the camera to the point (the near plane's point at its
        // pixel lies on that line).
        let view = floor_with_a_step();
        for p in [Vec3::ZERO, Vec3::new(1.5, -2.0, 0.25), Vec3::new(-3.0, 1.0, -4.0)] {
            let expected = (p - Vec3::new(0.0, 0.0, 10.0)).normalize();
            assert!(view.eye_direction(p).distance(expected) < 1.0e-5, "{p} {}", view.eye_direction(p));
        }
        // Orthographic, turned: along the view's axis at any point.
        let view_from_world = Mat4::look_at_rh(Vec3::new(3.0, 4.0, 5.0), Vec3::ZERO, Vec3::Y);
        // (Bevy's reverse Z: its near plane at depth 1.)
        let clip_from_view = Mat4::orthographic_rh(-4.0, 4.0, -4.0, 4.0, 100.0, 0.1);
        let ortho = ViewDepth {
            clip_from_world: clip_from_view * view_from_world,
            view_from_world,
            view_from_clip: clip_from_view.inverse(),
            ..view
        };
        let axis = -Vec3::new(3.0, 4.0, 5.0).normalize();
        for p in [Vec3::ZERO, Vec3::new(1.0, -1.0, 0.5)] {
            assert!(ortho.eye_direction(p).distance(axis) < 1.0e-5, "{p} {}", ortho.eye_direction(p));
        }
    }

    #[test]
    fn a_pixel_measures_what_the_view_shows_of_it() {
        // Perspective: the floor 10 units away, its points under two neighbouring pixels' centers.
        let view = floor_with_a_step();
        let world_from_clip = view.clip_from_world.inverse();
        let floor = |ndc: Vec2| {
            let near = world_from_clip.project_point3(ndc.extend(1.0));
            let dir = (world_from_clip.project_point3(ndc.extend(1.0e-4)) - near).normalize();
            near + dir * (near.z / -dir.z)
        };
        let step = floor(Vec2::new(-0.5 / 32.0, 0.5 / 32.0)).distance(floor(Vec2::new(-0.5 / 32.0, -0.5 / 32.0)));
        let w = (view.clip_from_world * Vec3::ZERO.extend(1.0)).w;
        assert!((view.pixel_size(w) - step).abs() < 1.0e-4 * step, "{} {step}", view.pixel_size(w));
        // Orthographic: 8 units tall on 64 pixels, at any depth.
        let clip_from_view = Mat4::orthographic_rh(-4.0, 4.0, -4.0, 4.0, 0.1, 100.0);
        let ortho = ViewDepth { view_from_clip: clip_from_view.inverse(), clip_from_world: clip_from_view, ..view };
        assert!((ortho.pixel_size(1.0) - 8.0 / 64.0).abs() < 1.0e-6);
    }

    #[test]
    fn the_lift_is_half_a_pixel_at_most_an_eighth_of_a_cell() {
        // Pixels a tenth of a cell (a fine view): half a pixel.
        assert_eq!(contact_lift(0.1, 1.0), 0.05);
        // Pixels half a cell (a small object seen whole): an eighth of the cell, not a quarter.
        assert_eq!(contact_lift(0.5, 1.0), 0.125);
        // The two meet where a pixel is a quarter of a cell.
        assert_eq!(contact_lift(0.25, 1.0), 0.125);
    }

    #[test]
    fn a_ray_into_a_step_finds_it_and_rays_over_open_floor_do_not() {
        let view = floor_with_a_step();
        let mut loads = 0;
        let cell = 0.5;
        // From the floor just before the step, toward it: inside the step within two cells.
        let toward = Vec3::new(1.0, 0.0, 0.3).normalize();
        let (from, reach) = (Vec3::new(-0.2, 0.0, 0.0), 2.0 * cell);
        let t = depth_contact(&view, from, Vec3::Z, toward, cell, reach, CONTACT_SAMPLES, 0.5, None, &mut loads);
        assert!(t.is_some_and(|t| t > 0.1 && t < 0.5), "{t:?}");
        // Away from it, and up: open.
        for dir in [Vec3::new(-1.0, 0.0, 0.3).normalize(), Vec3::Z, Vec3::new(0.0, 1.0, 0.2).normalize()] {
            for jitter in [0.0, 0.5, 0.99] {
                let at = Vec3::new(-1.5, 0.3, 0.0);
                let t = depth_contact(&view, at, Vec3::Z, dir, cell, reach, CONTACT_SAMPLES, jitter, None, &mut loads);
                assert_eq!(t, None);
            }
        }
        assert!(loads > 0);
    }

    #[test]
    fn points_far_behind_a_surface_or_off_the_view_are_not_contacts() {
        let view = floor_with_a_step();
        let mut loads = 0;
        // Under the step's top by 0.15: inside it for a thickness above that, not below.
        assert!(view.behind(Vec3::new(0.5, 0.0, 0.1), 1.0, false, &mut loads));
        assert!(!view.behind(Vec3::new(0.5, 0.0, 0.1), 0.1, false, &mut loads));
        // Above the surface, and beside the view.
        assert!(!view.behind(Vec3::new(0.5, 0.0, 0.4), 1.0, false, &mut loads));
        assert!(!view.behind(Vec3::new(50.0, 0.0, 0.0), 1.0, false, &mut loads));
        // Behind the camera.
        assert!(!view.behind(Vec3::new(0.0, 0.0, 20.0), 1.0, false, &mut loads));
    }

    #[test]
    fn under_a_surface_the_view_grazes_the_thickness_reaches_deeper_along_the_view() {
        let view = floor_with_a_step();
        let mut loads = 0;
        // Seen head on, 0.15 under the step's top is deeper than 0.1.
        assert!(!view.behind(Vec3::new(0.5, 0.0, 0.1), 0.1, false, &mut loads));
        // The same depths where the view grazes the surfaces it shows (their normals at 76 degrees to it):
        // a thickness of 0.1 along the normal is 0.4 along the view, not more.
        let tilted = Vec3::new(0.97, 0.0, 0.243).normalize();
        let grazing = ViewDepth { normals: view.normals.iter().map(|_| tilted).collect(), ..view };
        let before = loads;
        assert!(grazing.behind(Vec3::new(0.5, 0.0, 0.1), 0.1, true, &mut loads));
        assert_eq!(loads, before + 2, "the normal is read where the point lies deeper than the thickness");
        assert!(!grazing.behind(Vec3::new(0.5, 0.0, -0.3), 0.1, true, &mut loads));
        // Not asked to measure along the normal, it does not.
        assert!(!grazing.behind(Vec3::new(0.5, 0.0, 0.1), 0.1, false, &mut loads));
    }

    /// A contact point deeper along the view than the thickness, within it along the grazed surface's normal,
    /// counts only inside that surface's voxels: a floor ray running under the step's edge stops there where
    /// the step's side is voxelized, and not where the voxels are empty (as behind a bar thinner than a cell,
    /// seen edge on), nor without the level.
    #[test]
    fn a_contact_along_the_grazed_normal_needs_the_voxels_there() {
        use crate::cpu::grid::{VoxelGrid, VoxelOccupancy};
        use crate::cpu::march::VoxelMips;
        let view = floor_with_a_step();
        let tilted = Vec3::new(0.97, 0.0, 0.243).normalize();
        let grazing = ViewDepth { normals: view.normals.iter().map(|_| tilted).collect(), ..view };
        // Cells of 0.1: the floor (z = 0) in the middle of layer 7, the step's side (x = 0) in column 16.
        let grid = VoxelGrid::new(Vec3::new(-1.6, -1.6, -0.75), 0.1, glam::UVec3::splat(32)).unwrap();
        let (side, empty) = (VoxelOccupancy::new(grid, false), VoxelOccupancy::new(grid, false));
        for j in 0..32 {
            for k in 7..=9 {
                side.set(glam::UVec3::new(16, j, k));
            }
        }
        let (side, empty) = (VoxelMips::new(&side, 4), VoxelMips::new(&empty, 4));
        let level = |mips| TraceLevel { origin: grid.origin, cell_size: 0.1, window_min: glam::IVec3::ZERO, mips };
        let (from, dir) = (Vec3::new(-0.05, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.2).normalize());
        let contact = |grazing_level: Option<&TraceLevel>| {
            depth_contact(&grazing, from, Vec3::Z, dir, 0.1, 0.2, CONTACT_SAMPLES, 0.5, grazing_level, &mut 0)
        };
        // Its points past x = 0 lie 0.22-0.24 under the step's top: deeper than a cell (0.1) along the view.
        let t = contact(Some(&level(&side)));
        assert!(t.is_some_and(|t| (from + dir * t).x > 0.0), "{t:?}");
        assert_eq!(contact(Some(&level(&empty))), None);
        assert_eq!(contact(None), None);
    }
}
