//! A sampler of glTF animation clips: the node transforms (translation, rotation, scale) a clip gives at a
//! time, with step, linear (spherical for rotations) and cubic-spline interpolation as the glTF 2.0 spec
//! defines them. Used to pose a glTF file before voxelizing it on the CPU (`voxelize --animation`), the
//! twin of Bevy's `AnimationPlayer` sought to the same time.
//!
//! Morph-target weight channels give the weights of the node's mesh at that time (each target's weight
//! interpolated on its own).

use super::gltf_file::MAX_ACCESSOR_COUNT;
use glam::{Quat, Vec3};
use gltf::animation::util::ReadOutputs;
use gltf::animation::{Interpolation, Property};
use std::collections::HashMap;

/// One clip of a file: its index, name and length.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationInfo {
    /// Index in the file's `animations`.
    pub index: usize,
    /// Its name, if it has one.
    pub name: Option<String>,
    /// The last keyframe time, in seconds.
    pub duration: f32,
    /// Its channels.
    pub channels: usize,
}

/// What a clip sets on one node at a time (`None`: the node's own value stands).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodePose {
    /// Translation.
    pub translation: Option<Vec3>,
    /// Rotation (unit).
    pub rotation: Option<Quat>,
    /// Scale.
    pub scale: Option<Vec3>,
    /// The morph-target weights of the node's mesh.
    pub weights: Option<Vec<f32>>,
}

/// Whether reading `accessor` stays within the file's bytes: at most [`MAX_ACCESSOR_COUNT`] elements and no
/// more bytes than the buffers hold (a sparse accessor without a buffer view would otherwise yield as many
/// zeros as its count asks, from a file of a few hundred bytes).
pub(crate) fn accessor_fits(accessor: &gltf::Accessor, buffers: &[Vec<u8>]) -> bool {
    let total: u64 = buffers.iter().map(|b| b.len() as u64).sum();
    accessor.count() <= MAX_ACCESSOR_COUNT && accessor.count() as u64 * accessor.size() as u64 <= total
}

/// The clips of a document.
pub fn animation_infos(document: &gltf::Document, buffers: &[Vec<u8>]) -> Vec<AnimationInfo> {
    document
        .animations()
        .map(|a| {
            let duration = a
                .channels()
                .filter(|c| accessor_fits(&c.sampler().input(), buffers))
                .filter_map(|c| {
                    let reader = c.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
                    reader.read_inputs().and_then(|i| i.fold(None, |m: Option<f32>, t| Some(m.map_or(t, |m| m.max(t)))))
                })
                .fold(0.0f32, f32::max);
            AnimationInfo {
                index: a.index(),
                name: a.name().map(str::to_string),
                duration,
                channels: a.channels().count(),
            }
        })
        .collect()
}

/// Finds a clip by name or index.
pub fn find_animation(document: &gltf::Document, name_or_index: &str) -> Result<usize, String> {
    let count = document.animations().count();
    if let Some(a) = document.animations().find(|a| a.name() == Some(name_or_index)) {
        return Ok(a.index());
    }
    match name_or_index.parse::<usize>() {
        Ok(i) if i < count => Ok(i),
        _ => Err(format!(
            "no animation {name_or_index:?} (the file has {count}: {})",
            document
                .animations()
                .map(|a| format!("{} {:?}", a.index(), a.name().unwrap_or("")))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Values that can be interpolated along a channel.
trait Keyframe: Copy {
    fn lerp_to(self, other: Self, s: f32) -> Self;
    fn scaled(self, k: f32) -> Self;
    fn plus(self, other: Self) -> Self;
    fn finish(self) -> Self {
        self
    }
}

impl Keyframe for Vec3 {
    fn lerp_to(self, other: Self, s: f32) -> Self {
        self.lerp(other, s)
    }
    fn scaled(self, k: f32) -> Self {
        self * k
    }
    fn plus(self, other: Self) -> Self {
        self + other
    }
}

impl Keyframe for f32 {
    fn lerp_to(self, other: Self, s: f32) -> Self {
        self + (other - self) * s
    }
    fn scaled(self, k: f32) -> Self {
        self * k
    }
    fn plus(self, other: Self) -> Self {
        self + other
    }
}

/// Morph weights at `t`: `outputs` holds, per keyframe, one value per target (for cubic splines the in
/// tangents, values and out tangents of all targets), each target interpolated on its own.
fn sample_weights(inputs: &[f32], outputs: &[f32], interpolation: Interpolation, t: f32) -> Option<Vec<f32>> {
    let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
    if inputs.is_empty() || !outputs.len().is_multiple_of(inputs.len() * per_key) {
        return None;
    }
    let targets = outputs.len() / (inputs.len() * per_key);
    (0..targets)
        .map(|target| {
            // This target's series, laid out as `sample` expects (triplets per key for cubic splines).
            let series: Vec<f32> = (0..inputs.len())
                .flat_map(|k| (0..per_key).map(move |part| outputs[(k * per_key + part) * targets + target]))
                .collect();
            sample(inputs, &series, interpolation, t)
        })
        .collect()
}

impl Keyframe for Quat {
    fn lerp_to(self, other: Self, s: f32) -> Self {
        self.slerp(other, s)
    }
    fn scaled(self, k: f32) -> Self {
        self * k
    }
    fn plus(self, other: Self) -> Self {
        self + other
    }
    fn finish(self) -> Self {
        self.normalize()
    }
}

/// The channel's value at `t` (clamped to its keyframes). For cubic splines `outputs` holds triplets (in
/// tangent, value, out tangent) per keyframe, as the spec lays them out.
fn sample<T: Keyframe>(inputs: &[f32], outputs: &[T], interpolation: Interpolation, t: f32) -> Option<T> {
    let cubic = interpolation == Interpolation::CubicSpline;
    let per_key = if cubic { 3 } else { 1 };
    if inputs.is_empty() || outputs.len() < inputs.len() * per_key {
        return None;
    }
    let value = |k: usize| outputs[k * per_key + if cubic { 1 } else { 0 }];
    let last = inputs.len() - 1;
    if !(t > inputs[0]) {
        return Some(value(0).finish());
    }
    if t >= inputs[last] {
        return Some(value(last).finish());
    }
    // The keyframe at or before t.
    let k = inputs.partition_point(|&x| x <= t).saturating_sub(1).min(last - 1);
    let dt = inputs[k + 1] - inputs[k];
    let s = if dt > 0.0 { (t - inputs[k]) / dt } else { 0.0 };
    Some(match interpolation {
        Interpolation::Step => value(k),
        Interpolation::Linear => value(k).lerp_to(value(k + 1), s),
        Interpolation::CubicSpline => {
            let (s2, s3) = (s * s, s * s * s);
            let out_tangent = outputs[k * 3 + 2];
            let in_tangent = outputs[(k + 1) * 3];
            value(k)
                .scaled(2.0 * s3 - 3.0 * s2 + 1.0)
                .plus(out_tangent.scaled((s3 - 2.0 * s2 + s) * dt))
                .plus(value(k + 1).scaled(-2.0 * s3 + 3.0 * s2))
                .plus(in_tangent.scaled((s3 - s2) * dt))
                .finish()
        }
    })
}

/// The node transforms clip `animation` sets at `time` seconds. Channels that cannot be read are reported
/// in `warnings` and skipped.
pub fn sample_animation(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    animation: usize,
    time: f32,
    warnings: &mut Vec<String>,
) -> HashMap<usize, NodePose> {
    let mut poses: HashMap<usize, NodePose> = HashMap::new();
    let Some(anim) = document.animations().nth(animation) else { return poses };
    for channel in anim.channels() {
        let reader = channel.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
        let interpolation = channel.sampler().interpolation();
        let node = channel.target().node().index();
        let sampler = channel.sampler();
        if !(accessor_fits(&sampler.input(), buffers) && accessor_fits(&sampler.output(), buffers)) {
            warnings.push(format!(
                "animation {animation}: a channel of node {node} declares more keyframes than the file holds; skipped"
            ));
            continue;
        }
        let Some(inputs) = reader.read_inputs().map(|i| i.collect::<Vec<f32>>()) else {
            warnings.push(format!("animation {animation}: a channel without keyframe times; skipped"));
            continue;
        };
        let pose = poses.entry(node).or_default();
        let sampled = match (channel.target().property(), reader.read_outputs()) {
            (Property::Translation, Some(ReadOutputs::Translations(v))) => {
                let v: Vec<Vec3> = v.map(Vec3::from).collect();
                sample(&inputs, &v, interpolation, time).map(|x| pose.translation = Some(x))
            }
            (Property::Scale, Some(ReadOutputs::Scales(v))) => {
                let v: Vec<Vec3> = v.map(Vec3::from).collect();
                sample(&inputs, &v, interpolation, time).map(|x| pose.scale = Some(x))
            }
            (Property::Rotation, Some(ReadOutputs::Rotations(v))) => {
                let v: Vec<Quat> = v.into_f32().map(Quat::from_array).collect();
                sample(&inputs, &v, interpolation, time).map(|x| pose.rotation = Some(x))
            }
            (Property::MorphTargetWeights, Some(ReadOutputs::MorphTargetWeights(v))) => {
                let v: Vec<f32> = v.into_f32().collect();
                sample_weights(&inputs, &v, interpolation, time).map(|w| pose.weights = Some(w))
            }
            _ => None,
        };
        if sampled.is_none() {
            warnings.push(format!("animation {animation}: a channel of node {node} could not be read; skipped"));
        }
    }
    poses
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channels_interpolate_as_the_spec_says() {
        let times = [0.0, 1.0, 3.0];
        let v = [Vec3::ZERO, Vec3::X, Vec3::new(3.0, 2.0, 0.0)];
        assert_eq!(sample(&times, &v, Interpolation::Linear, 0.5), Some(Vec3::new(0.5, 0.0, 0.0)));
        assert_eq!(sample(&times, &v, Interpolation::Linear, 2.0), Some(Vec3::new(2.0, 1.0, 0.0)));
        assert_eq!(sample(&times, &v, Interpolation::Step, 2.9), Some(Vec3::X));
        assert_eq!(sample(&times, &v, Interpolation::Linear, -1.0), Some(Vec3::ZERO), "clamped before");
        assert_eq!(sample(&times, &v, Interpolation::Linear, 9.0), Some(v[2]), "clamped after");
        // Rotations: spherical, unit length.
        let q = [Quat::IDENTITY, Quat::from_rotation_y(std::f32::consts::FRAC_PI_2)];
        let half = sample(&[0.0, 1.0], &q, Interpolation::Linear, 0.5).unwrap();
        assert!(half.abs_diff_eq(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4), 1e-5), "{half}");
        // Cubic spline with zero tangents: the smoothstep between values; at the keys, the values.
        let z = Vec3::ZERO;
        let cubic = [z, Vec3::ZERO, z, z, Vec3::X * 4.0, z];
        assert_eq!(sample(&[0.0, 2.0], &cubic, Interpolation::CubicSpline, 1.0), Some(Vec3::X * 2.0));
        assert_eq!(sample(&[0.0, 2.0], &cubic, Interpolation::CubicSpline, 2.0), Some(Vec3::X * 4.0));
        // With an out tangent of 1 unit/s at the first key, the curve leaves it along that tangent.
        let tangent = [z, Vec3::ZERO, Vec3::Y, z, Vec3::ZERO, z];
        let early = sample(&[0.0, 2.0], &tangent, Interpolation::CubicSpline, 0.01).unwrap();
        assert!((early.y - 0.01).abs() < 1e-3, "{early}");
        // Morph weights: two targets, each interpolated on its own; cubic splines read the middle of each
        // triplet at the keys.
        let w = [0.0, 1.0, 1.0, 0.0];
        assert_eq!(sample_weights(&[0.0, 1.0], &w, Interpolation::Linear, 0.25), Some(vec![0.25, 0.75]));
        let cubic_w = [0.0, 0.0, 0.2, 0.4, 0.0, 0.0, 0.0, 0.0, 0.6, 0.8, 0.0, 0.0];
        assert_eq!(sample_weights(&[0.0, 1.0], &cubic_w, Interpolation::CubicSpline, 1.0), Some(vec![0.6, 0.8]));
        // Too few outputs: nothing.
        assert_eq!(sample(&[0.0, 1.0], &v[..1], Interpolation::Linear, 0.5), None);
    }
}
