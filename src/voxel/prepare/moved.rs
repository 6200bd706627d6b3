//! Which dynamic occluders' voxels changed this frame, and how far they moved. A dynamic occluder is
//! voxelized every frame, but only one that moved, turned, deformed, appeared or went changes the voxels:
//! the temporal passes keep a shorter history only around those (`VoxelGrid::moved`), so that a dynamic
//! occluder standing still converges as a static one does. (Static occluders added to the static grid,
//! changed or taken out of it are listed beside them, by `ResolvedOccluders`, with an unknown motion.)

use bevy::prelude::*;

/// What a dynamic occluder's voxels are made from besides its mesh: its transform (or its skin's joint
/// matrices, world space), its morph weights, its mesh's place in the slabs, and its bounds.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Pose {
    /// `world_from_local`, or the joint matrices of a skinned mesh.
    pub transforms: Vec<Mat4>,
    /// The morph weights of a morphed mesh (empty otherwise).
    pub weights: Vec<f32>,
    /// The mesh and where its vertices and indices lie (a new upload changes the shape).
    pub mesh: (AssetId<Mesh>, [u32; 4]),
    /// World bounds (`None`: unknown).
    pub bounds: Option<(Vec3, Vec3)>,
}

/// An occluder whose voxels changed since last frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovedOccluder {
    /// The box around it now and last frame (`None`: unknown, anywhere).
    pub bounds: Option<(Vec3, Vec3)>,
    /// The farthest any point of it moved since last frame, in world units: infinite where that is not known
    /// (it appeared, went, or changed its mesh or bounds-less shape).
    pub motion: f32,
}

impl MovedOccluder {
    /// One change where `a`, `b` or both happened (both: the box around both, the larger motion).
    pub(super) fn either(a: Option<Self>, b: Option<Self>) -> Option<Self> {
        match (a, b) {
            (Some(a), Some(b)) => Some(MovedOccluder {
                bounds: a.bounds.zip(b.bounds).map(|((a0, a1), (b0, b1))| (a0.min(b0), a1.max(b1))),
                motion: a.motion.max(b.motion),
            }),
            (a, b) => a.or(b),
        }
    }
}

/// How a dynamic occluder's voxels changed from last frame's pose to this frame's (`None`: not dynamic or
/// not resolved in that frame); `None` if they did not.
pub(super) fn moved(prev: Option<&Pose>, now: Option<&Pose>) -> Option<MovedOccluder> {
    match (prev, now) {
        (None, None) => None,
        (Some(p), Some(n)) if p == n => None,
        (Some(p), Some(n)) => {
            let bounds = p.bounds.zip(n.bounds).map(|((a, b), (c, d))| (a.min(c), b.max(d)));
            let motion = if p.mesh != n.mesh || p.transforms.len() != n.transforms.len() || bounds.is_none() {
                f32::INFINITY
            } else {
                let (lo, hi) = p.bounds.unwrap_or_default();
                let mut motion = p
                    .transforms
                    .iter()
                    .zip(&n.transforms)
                    .map(|(a, b)| corner_motion(*a, *b, lo, hi))
                    .fold(0.0, f32::max);
                // Morph targets move vertices by an unknown amount: a change of weight counts as moving the
                // whole box's diagonal by it.
                let weights = p
                    .weights
                    .iter()
                    .zip(&n.weights)
                    .map(|(a, b)| if (a - b).is_finite() { (a - b).abs() } else { f32::INFINITY })
                    .fold(0.0, f32::max);
                if p.weights.len() != n.weights.len() {
                    motion = f32::INFINITY;
                }
                motion + weights * (hi - lo).length()
            };
            Some(MovedOccluder { bounds, motion: if motion.is_nan() { f32::INFINITY } else { motion } })
        }
        (Some(o), None) | (None, Some(o)) => Some(MovedOccluder { bounds: o.bounds, motion: f32::INFINITY }),
    }
}

/// The farthest a point of the box `(lo, hi)` placed by `before` moves when placed by `after` instead: at
/// a corner, since the displacement `after * before^-1 - 1` is affine.
fn corner_motion(before: Mat4, after: Mat4, lo: Vec3, hi: Vec3) -> f32 {
    let relative = after * before.inverse();
    (0..8)
        .map(|k| {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            // (`max` would pass over a NaN: a transform that is not finite moved by an unknown amount.)
            let d = relative.transform_point3(c).distance(c);
            if d.is_finite() { d } else { f32::INFINITY }
        })
        .fold(0.0, f32::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(t: Mat4) -> Pose {
        let (lo, hi) = (Vec3::splat(-0.5), Vec3::splat(0.5));
        let corners = (0..8).map(|k| {
            t.transform_point3(Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            ))
        });
        let bounds = corners.fold((Vec3::MAX, Vec3::MIN), |(a, b), c| (a.min(c), b.max(c)));
        Pose { transforms: vec![t], weights: vec![], mesh: (AssetId::default(), [0, 24, 0, 12]), bounds: Some(bounds) }
    }

    #[test]
    fn a_still_occluder_has_not_moved_and_a_moving_one_moved_as_far_as_its_farthest_point() {
        let still = pose(Mat4::from_translation(Vec3::new(1.0, 0.5, 0.0)));
        assert_eq!(moved(Some(&still), Some(&still.clone())), None);
        assert_eq!(moved(None, None), None);
        // Slid 2 cm: every point moved 2 cm, and the box covers both places.
        let slid = pose(Mat4::from_translation(Vec3::new(1.02, 0.5, 0.0)));
        let m = moved(Some(&still), Some(&slid)).unwrap();
        assert!((m.motion - 0.02).abs() < 1e-5, "{}", m.motion);
        let (lo, hi) = m.bounds.unwrap();
        assert!((lo.x - 0.5).abs() < 1e-5 && (hi.x - 1.52).abs() < 1e-5);
        // Turned in place by 0.1 rad about its centre: its corners (sqrt(2)/2 from the axis) moved most.
        let turned = pose(Mat4::from_translation(Vec3::new(1.0, 0.5, 0.0)) * Mat4::from_rotation_y(0.1));
        let m = moved(Some(&still), Some(&turned)).unwrap();
        let chord = 2.0 * (0.5f32.sqrt()) * (0.05f32).sin();
        assert!((m.motion - chord).abs() < 1e-3, "{} {chord}", m.motion);
    }

    #[test]
    fn what_appears_goes_or_changes_shape_moved_by_an_unknown_amount() {
        let a = pose(Mat4::IDENTITY);
        for m in [moved(None, Some(&a)), moved(Some(&a), None)] {
            let m = m.unwrap();
            assert_eq!(m.bounds, a.bounds);
            assert!(m.motion.is_infinite());
        }
        let mut remeshed = a.clone();
        remeshed.mesh.1[1] = 48;
        assert!(moved(Some(&a), Some(&remeshed)).unwrap().motion.is_infinite());
        let mut unbounded = a.clone();
        unbounded.bounds = None;
        unbounded.transforms[0] = Mat4::from_translation(Vec3::X);
        let m = moved(Some(&a), Some(&unbounded)).unwrap();
        assert!(m.bounds.is_none() && m.motion.is_infinite());
        // A NaN transform moved by an unknown amount too.
        let mut broken = a.clone();
        broken.transforms[0] = Mat4::from_translation(Vec3::NAN);
        assert!(moved(Some(&a), Some(&broken)).unwrap().motion.is_infinite());
    }

    #[test]
    fn a_change_of_morph_weight_moves_the_box_diagonal_by_it() {
        let mut a = pose(Mat4::IDENTITY);
        a.weights = vec![0.0, 0.5];
        let mut b = a.clone();
        b.weights[1] = 0.6;
        let m = moved(Some(&a), Some(&b)).unwrap();
        assert!((m.motion - 0.1 * 3.0f32.sqrt()).abs() < 1e-4, "{}", m.motion);
    }

    #[test]
    fn two_changes_of_one_occluder_cover_both_boxes_with_the_larger_motion() {
        let m = |lo: f32, motion: f32| MovedOccluder { bounds: Some((Vec3::splat(lo), Vec3::splat(lo + 1.0))), motion };
        assert_eq!(MovedOccluder::either(None, None), None);
        assert_eq!(MovedOccluder::either(Some(m(0.0, 0.1)), None), Some(m(0.0, 0.1)));
        assert_eq!(MovedOccluder::either(None, Some(m(2.0, 0.3))), Some(m(2.0, 0.3)));
        let both = MovedOccluder::either(Some(m(0.0, 0.1)), Some(m(2.0, f32::INFINITY))).unwrap();
        assert_eq!(both.bounds, Some((Vec3::ZERO, Vec3::splat(3.0))));
        assert!(both.motion.is_infinite());
        // Either without bounds: anywhere.
        let anywhere = MovedOccluder { bounds: None, motion: 0.2 };
        assert_eq!(MovedOccluder::either(Some(m(0.0, 0.1)), Some(anywhere)).unwrap().bounds, None);
    }
}
