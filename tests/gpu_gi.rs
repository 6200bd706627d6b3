//! Voxel global illumination on a headless Bevy app (lavapipe here), read back and held against its CPU
//! twin.

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::gpu_readback::Readback;
use bevy_hao::cpu::VoxelAttributes;
use bevy_hao::cpu::lighting::{Light, bounced_radiance, unpack_rgb9e5, voxel_radiance};
use bevy_hao::cpu::probes::{LitVoxels, gather_probe, probe_rotation, relocate_probe};
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::*;

const SIZE: UVec2 = UVec2::new(64, 48);

/// The render target of the room's camera.
#[derive(Resource, Clone)]
struct Target(Handle<Image>);

#[derive(Component)]
struct Bulb;

/// A room of parts in their colours: a floor, a roof over half of it, a box on the floor and a red wall; a
/// sun, a point light under the roof and a spot light; a camera with voxel GI.
fn lit_room(volume: VoxelVolume, gi: VoxelGlobalIllumination) -> App {
    headless_app(move |app| {
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>| {
                commands.spawn(volume);
                let mut part = |size: Vec3, at: Vec3, color: Color| {
                    commands.spawn((
                        Mesh3d(meshes.add(Cuboid::from_size(size))),
                        MeshMaterial3d(materials.add(StandardMaterial { base_color: color, ..default() })),
                        Transform::from_translation(at),
                        StaticOccluder,
                    ));
                };
                part(Vec3::new(6.0, 0.2, 6.0), Vec3::new(0.0, -2.1, 0.0), Color::srgb(0.8, 0.8, 0.8));
                part(Vec3::new(3.0, 0.2, 6.0), Vec3::new(-1.5, 0.1, 0.0), Color::srgb(0.7, 0.7, 0.7));
                part(Vec3::new(0.8, 0.8, 0.8), Vec3::new(1.2, -1.6, 0.6), Color::srgb(0.2, 0.3, 0.9));
                part(Vec3::new(0.2, 3.0, 6.0), Vec3::new(2.9, -0.5, 0.0), Color::srgb(0.9, 0.1, 0.1));
                commands.spawn((
                    DirectionalLight { illuminance: 10_000.0, color: Color::srgb(1.0, 0.95, 0.9), ..default() },
                    Transform::default().looking_to(Vec3::new(0.8, -1.5, 0.4), Vec3::Y),
                ));
                commands.spawn((
                    PointLight { intensity: 200_000.0, range: 8.0, color: Color::srgb(1.0, 0.6, 0.3), ..default() },
                    Transform::from_xyz(-1.5, -0.8, 1.0),
                    Bulb,
                ));
                commands.spawn((
                    SpotLight { intensity: 400_000.0, range: 10.0, inner_angle: 0.25, outer_angle: 0.5, ..default() },
                    Transform::from_xyz(1.0, 2.5, -1.5).looking_at(Vec3::new(1.2, -2.0, -1.0), Vec3::Y),
                ));
                let color = target_image(&mut images, SIZE);
                commands.insert_resource(Target(color.clone()));
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(color.into()),
                    Transform::from_xyz(0.0, 1.0, 3.5).looking_at(Vec3::new(0.0, -1.5, 0.0), Vec3::Y),
                    gi.clone(),
                ));
            },
        );
    })
}

/// The lights of the app's world as the plugin extracts them (Bevy's components: linear colour, a light's
/// forward the way its light travels).
fn world_lights(app: &mut App) -> Vec<Light> {
    let linear = |c: Color| {
        let l = c.to_linear();
        Vec3::new(l.red, l.green, l.blue)
    };
    let world = app.world_mut();
    let mut lights = Vec::new();
    for (l, t) in world.query::<(&DirectionalLight, &GlobalTransform)>().iter(world) {
        lights.push(Light::Directional {
            direction: t.forward().as_vec3(),
            color: linear(l.color),
            illuminance: l.illuminance,
        });
    }
    for (l, t) in world.query::<(&PointLight, &GlobalTransform)>().iter(world) {
        lights.push(Light::Point {
            position: t.translation(),
            color: linear(l.color),
            intensity: l.intensity,
            range: l.range,
        });
    }
    for (l, t) in world.query::<(&SpotLight, &GlobalTransform)>().iter(world) {
        lights.push(Light::Spot {
            position: t.translation(),
            direction: t.forward().as_vec3(),
            color: linear(l.color),
            intensity: l.intensity,
            range: l.range,
            inner_angle: l.inner_angle,
            outer_angle: l.outer_angle,
        });
    }
    lights
}

/// What the lighting volume holds against its CPU twin: how many occupied voxels were compared, how many
/// are lit, how many agree, and the largest difference among those that agree (relative to the larger
/// channel).
struct Parity {
    voxels: u32,
    lit: u32,
    /// Of them, lit by the lights themselves.
    lit_by_lights: u32,
    agree: u32,
    worst: f32,
}

/// Reads the grid (its levels, attributes and the lighting volume) back and holds every occupied voxel's
/// radiance against `cpu::lighting::voxel_radiance` with the GPU's own attributes (as their textures hold
/// them) and the world's lights (with a bounce feedback of 0).
fn lighting_parity(app: &mut App) -> Parity {
    let gi = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    // The lighting volume first, as the next frame leaves it; the scene's voxels do not change after.
    let (w, h, radiance_texel, radiance) = read_image(app, gi.radiance, 0);
    assert_eq!(radiance_texel, 4);
    compare_lighting(app, w, h, &radiance, None)
}

/// The light the probes send back into the voxels (`bounced_radiance`) as the lighting pass reads it: the
/// window, the records as they were when it ran, and the feedback.
struct Bounce<'a> {
    window: bevy_hao::cpu::probes::ProbeWindow,
    records: &'a [u8],
    feedback: f32,
}

/// Holds the lighting volume `radiance` (`w` x `h` texels a slice, read back) against its CPU twin, voxel
/// for voxel: `voxel_radiance`, plus `bounced_radiance` from the records of `bounce` where given.
fn compare_lighting(app: &mut App, w: u32, h: u32, radiance: &[u8], bounce: Option<Bounce>) -> Parity {
    let grid = grid_assets(app).expect("a voxel grid");
    let [albedo_image, normal_image] = grid.attributes.clone().expect("attributes kept for GI");
    let voxels = read_trace_voxels(app);
    let levels = trace_levels(&voxels);
    let (_, _, texel, albedo) = read_image(app, albedo_image, 0);
    let (_, _, _, normal) = read_image(app, normal_image, 0);
    assert_eq!(texel, 4);
    let lights = world_lights(app);
    // Each lattice point's record, as the lighting pass reads it: its faces and where it gathered from, or
    // none for a slot another lattice point holds or one not yet gathered.
    let probe = |q: IVec3| {
        let b = bounce.as_ref()?;
        let slot = b.window.slot(q);
        let (faces, lattice, frames, _) = record(b.records, slot);
        (lattice == q && frames > 0).then(|| (faces, record_at(b.records, slot)))
    };
    let feedback = bounce.as_ref().map_or(0.0, |b| b.feedback);
    let windows: Vec<IVec3> = match grid.cascades {
        Some(_) => stats(app).cascades.iter().map(|c| c.window_min).collect(),
        None => vec![IVec3::ZERO],
    };
    let size = grid.texture_size;
    let mut p = Parity { voxels: 0, lit: 0, lit_by_lights: 0, agree: 0, worst: 0.0 };
    for (l, level) in levels.iter().enumerate() {
        let dims = level.mips.dims();
        let wrap = windows[l].rem_euclid(dims.as_ivec3()).as_uvec3();
        for z in 0..dims.z {
            for y in 0..dims.y {
                for x in 0..dims.x {
                    let cell = UVec3::new(x, y, z);
                    let stored = (cell + wrap) % dims + UVec3::new(0, 0, l as u32 * size.z);
                    let t = (((stored.z * h + stored.y) * w + stored.x) * 4) as usize;
                    let gpu = unpack_rgb9e5(u32::from_le_bytes(radiance[t..t + 4].try_into().unwrap()));
                    if !level.mips.occupied(cell.as_ivec3()) {
                        assert_eq!(gpu, Vec3::ZERO, "level {l} cell {cell}: an empty voxel is unlit");
                        continue;
                    }
                    let a = &albedo[t..t + 4];
                    let n = &normal[t..t + 4];
                    let snorm = |b: u8| (b as i8).max(-127) as f32 / 127.0;
                    let attributes = VoxelAttributes {
                        albedo: Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32) / 255.0,
                        normal: Vec3::new(snorm(n[0]), snorm(n[1]), snorm(n[2])),
                    };
                    let direct = voxel_radiance(&levels, l, cell.as_ivec3(), &attributes, &lights);
                    let bounced = match &bounce {
                        Some(b) => {
                            bounced_radiance(&levels, l, cell.as_ivec3(), &attributes, feedback, &b.window, probe)
                        }
                        None => Vec3::ZERO,
                    };
                    let cpu = direct + bounced;
                    p.voxels += 1;
                    p.lit_by_lights += (direct.max_element() > 0.0) as u32;
                    p.lit += (cpu.max_element() > 0.0) as u32;
                    // rgb9e5 keeps 1/512 of the largest channel; the rest is the GPU's rounding.
                    let scale = cpu.max_element().max(gpu.max_element()).max(1.0e-6);
                    let d = (gpu - cpu).abs().max_element() / scale;
                    if d <= 4.0 / 512.0 {
                        p.agree += 1;
                        p.worst = p.worst.max(d);
                    }
                }
            }
        }
    }
    p
}

/// The lighting volume on the GPU equals its CPU twin voxel for voxel, in one grid and in cascades (which
/// store their windows toroidally): every occupied voxel's radiance under a sun, a point light and a spot,
/// shadows included, from the voxels' own albedo and normal, within rgb9e5's precision, but for a few whose
/// shadow rays graze an occluder; empty voxels hold nothing. A light taken away leaves the voxels within
/// `lighting_frames` frames.
#[test]
fn the_lighting_volume_on_the_gpu_equals_its_cpu_twin() {
    let _gpu = gpu_lock();
    let single = VoxelVolume {
        bounds: VolumeBounds::World { min: Vec3::splat(-4.0), max: Vec3::splat(4.0) },
        resolution: VolumeResolution::Cells(64),
        ..default()
    };
    let cascades = VoxelVolume {
        bounds: VolumeBounds::FollowCamera { cascades: 2, cells: 32, finest_cell_size: 0.125 },
        ..default()
    };
    for (name, volume) in [("one grid", single), ("cascades", cascades)] {
        let lighting_frames = 3;
        let gi = VoxelGlobalIllumination { lighting_frames, bounce_feedback: 0.0, ..default() };
        let mut app = lit_room(volume, gi);
        run(&mut app, 10);
        let p = lighting_parity(&mut app);
        println!(
            "{name}: {} occupied voxels, {} lit by the CPU twin, {} within rgb9e5's precision of it (largest {:.5})",
            p.voxels, p.lit, p.agree, p.worst
        );
        assert!(p.voxels > 2_000 && p.lit * 4 > p.voxels, "{name}: {} voxels, {} lit", p.voxels, p.lit);
        assert!(p.agree * 1000 >= p.voxels * 995, "{name}: {} of {} voxels agree", p.agree, p.voxels);
        // The point light goes: within `lighting_frames` frames its light has left every voxel.
        let mut bulbs = app.world_mut().query_filtered::<Entity, With<Bulb>>();
        let bulb = bulbs.single(app.world()).unwrap();
        app.world_mut().despawn(bulb);
        run(&mut app, lighting_frames as usize - 1);
        let after = lighting_parity(&mut app);
        println!("{name}, the bulb gone: {} of {} voxels agree", after.agree, after.voxels);
        assert!(after.lit < p.lit, "{name}: {} lit with the bulb, {} without", p.lit, after.lit);
        assert!(after.agree * 1000 >= after.voxels * 995, "{name}: {} of {} agree", after.agree, after.voxels);
        assert!(take_render_errors().is_empty());
    }
}

/// The light the probes send back into the voxels on the GPU equals its CPU twin: with every voxel lit every
/// frame and a bounce feedback of 1, each occupied voxel holds `voxel_radiance` plus `bounced_radiance` from
/// the probes' records as the frame before left them (read back then), within rgb9e5's precision but for a
/// few whose shadow rays graze an occluder or a probe's line to it; and voxels the lights do not reach take
/// light from the probes that see them (of the room seen from inside, 8,124 of 12,725 voxels hold light
/// against 7,652 from the lights alone; those left dark face the dark outside the room or lie beyond the
/// probes' window).
#[test]
fn the_light_the_probes_send_back_on_the_gpu_equals_its_cpu_twin() {
    let _gpu = gpu_lock();
    let (volume, gi) = small_room_settings();
    let probe_counts = UVec3::new(16, 12, 16);
    let gi = VoxelGlobalIllumination { far_spacing: 0, lighting_frames: 1, bounce_feedback: 1.0, probe_counts, ..gi };
    let mut app = lit_room(volume, gi);
    // The window over the room, around the camera in it.
    look_from_inside(&mut app);
    run(&mut app, 12);
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let window = app.world().resource::<bevy_hao::GiProbeWindow>().0.expect("a probe window");
    // The records at the end of one frame, the lighting volume at the end of the next (lit from them).
    let [records, radiance] = read_in_turn(
        &mut app,
        [Readback::buffer(assets.probe_records.clone()), Readback::texture(assets.radiance.clone())],
    );
    let (w, h) = {
        let images = app.world().resource::<Assets<Image>>();
        let size = images.get(&assets.radiance).expect("the lighting volume").texture_descriptor.size;
        (size.width, size.height)
    };
    let row = (w * 4) as usize;
    let radiance: Vec<u8> = radiance.chunks(row.div_ceil(256) * 256).flat_map(|r| &r[..row]).copied().collect();
    let bounced =
        compare_lighting(&mut app, w, h, &radiance, Some(Bounce { window, records: &records, feedback: 1.0 }));
    let lit_by_lights = bounced.lit_by_lights;
    println!(
        "{} occupied voxels: {} hold light with the bounces ({} from the lights alone); {} agree with the CPU \
         twin (largest {:.5})",
        bounced.voxels, bounced.lit, lit_by_lights, bounced.agree, bounced.worst
    );
    assert!(bounced.voxels > 2_000, "{} voxels", bounced.voxels);
    assert!(bounced.lit > lit_by_lights + 100, "{} lit, {} by the lights", bounced.lit, lit_by_lights);
    assert!(bounced.agree * 1000 >= bounced.voxels * 995, "{} of {} voxels agree", bounced.agree, bounced.voxels);
    assert!(take_render_errors().is_empty());
}

/// Copies `readbacks` in consecutive frames, the first in one frame, the second in the next, and so on.
fn read_in_turn<const N: usize>(app: &mut App, readbacks: [Readback; N]) -> [Vec<u8>; N] {
    use bevy::render::gpu_readback::ReadbackComplete;
    use std::sync::{Arc, Mutex};
    let slots: [Arc<Mutex<Option<Vec<u8>>>>; N] = std::array::from_fn(|_| Default::default());
    let mut entities = Vec::new();
    for (readback, slot) in readbacks.into_iter().zip(slots.clone()) {
        let e = app
            .world_mut()
            .spawn(readback)
            .observe(move |ev: On<ReadbackComplete>| {
                slot.lock().unwrap().get_or_insert_with(|| ev.data.clone());
            })
            .id();
        entities.push(e);
        app.update();
        wait_for_gpu(app);
    }
    for _ in 0..20 {
        if slots.iter().all(|s| s.lock().unwrap().is_some()) {
            break;
        }
        app.update();
        wait_for_gpu(app);
    }
    for e in entities {
        app.world_mut().despawn(e);
    }
    slots.map(|s| s.lock().unwrap().take().expect("a readback within 20 frames"))
}

/// The lighting volume and the voxels' normals as read back, for the probes' CPU twin.
struct ReadVoxels<'a> {
    levels: &'a [bevy_hao::cpu::march::TraceLevel<'a>],
    windows: Vec<IVec3>,
    size: UVec3,
    width: u32,
    height: u32,
    radiance: Vec<u8>,
    normal: Vec<u8>,
}

impl ReadVoxels<'_> {
    /// The byte offset of a level's cell in the textures (levels stacked along z, windows stored
    /// toroidally).
    fn texel(&self, level: usize, cell: IVec3) -> usize {
        let dims = self.levels[level].mips.dims();
        let wrap = self.windows[level].rem_euclid(dims.as_ivec3()).as_uvec3();
        let s = (cell.as_uvec3() + wrap) % dims + UVec3::new(0, 0, level as u32 * self.size.z);
        (((s.z * self.height + s.y) * self.width + s.x) * 4) as usize
    }
}

impl LitVoxels for ReadVoxels<'_> {
    fn voxel(&self, level: usize, cell: IVec3) -> (Vec3, Vec3) {
        let t = self.texel(level, cell);
        let radiance = unpack_rgb9e5(u32::from_le_bytes(self.radiance[t..t + 4].try_into().unwrap()));
        let snorm = |b: u8| (b as i8).max(-127) as f32 / 127.0;
        let n = &self.normal[t..t + 3];
        (radiance, Vec3::new(snorm(n[0]), snorm(n[1]), snorm(n[2])))
    }
}

/// The probes' records and the irradiance volume, copied in the same frame (the irradiance volume without
/// its rows' padding).
fn read_records_and_volume(app: &mut App, assets: &bevy_hao::GiAssets) -> (Vec<u8>, Vec<u8>) {
    let [records, volume] = read_same_frame(
        app,
        [Readback::buffer(assets.probe_records.clone()), Readback::texture(assets.irradiance.clone())],
    );
    (records, unpadded(&volume, assets.probe_counts.x))
}

/// An irradiance volume's bytes read back without its rows' padding: rows of `width` texels of 8 bytes,
/// padded to 256 bytes.
fn unpadded(volume: &[u8], width: u32) -> Vec<u8> {
    let row = (width * 8) as usize;
    volume.chunks(row.next_multiple_of(256)).flat_map(|r| r[..row].to_vec()).collect()
}

/// Buffers and textures copied in the same frame.
fn read_same_frame<const N: usize>(app: &mut App, readbacks: [Readback; N]) -> [Vec<u8>; N] {
    use bevy::render::gpu_readback::ReadbackComplete;
    use std::sync::{Arc, Mutex};
    let slots: [Arc<Mutex<Option<Vec<u8>>>>; N] = std::array::from_fn(|_| Default::default());
    let entities: Vec<Entity> = readbacks
        .into_iter()
        .zip(slots.clone())
        .map(|(readback, slot)| {
            app.world_mut()
                .spawn(readback)
                .observe(move |ev: On<ReadbackComplete>| {
                    slot.lock().unwrap().get_or_insert_with(|| ev.data.clone());
                })
                .id()
        })
        .collect();
    for _ in 0..20 {
        app.update();
        wait_for_gpu(app);
        if slots.iter().all(|s| s.lock().unwrap().is_some()) {
            break;
        }
    }
    for e in entities {
        app.world_mut().despawn(e);
    }
    slots.map(|s| s.lock().unwrap().take().expect("a readback within 20 frames"))
}

/// A probe's faces as an irradiance volume of `counts` probes holds them at its index `c` (f16, Bevy's
/// layout: + and - faces in the halves of y, the x, y and z faces in the thirds of z).
fn stored_faces(volume: &[u8], counts: UVec3, c: UVec3) -> [Vec3; 6] {
    std::array::from_fn(|k| {
        let texel = UVec3::new(c.x, c.y + (k as u32 & 1) * counts.y, c.z + (k as u32 >> 1) * counts.z);
        let t = (((texel.z * 2 * counts.y + texel.y) * counts.x + texel.x) * 8) as usize;
        Vec3::new(f16_at(volume, t), f16_at(volume, t + 2), f16_at(volume, t + 4))
    })
}

/// Where a probe's record says it gathered from.
fn record_at(bytes: &[u8], slot: u32) -> Vec3 {
    let at = slot as usize * 128;
    let f = |k: usize| f32::from_le_bytes(bytes[at + 4 * k..at + 4 * k + 4].try_into().unwrap());
    Vec3::new(f(29), f(30), f(31))
}

/// A probe's record as the GPU wrote it: six faces, its lattice point, its updates, its last seed.
fn record(bytes: &[u8], slot: u32) -> ([Vec3; 6], IVec3, u32, u32) {
    let at = slot as usize * 128;
    let f = |k: usize| f32::from_le_bytes(bytes[at + 4 * k..at + 4 * k + 4].try_into().unwrap());
    let u = |k: usize| u32::from_le_bytes(bytes[at + 4 * k..at + 4 * k + 4].try_into().unwrap());
    let faces = std::array::from_fn(|j| Vec3::new(f(4 * j), f(4 * j + 1), f(4 * j + 2)));
    (faces, IVec3::new(u(24) as i32, u(25) as i32, u(26) as i32), u(27), u(28))
}

/// The probes on the GPU equal their CPU twin, and Bevy's PBR applies them: with a history of one update,
/// every probe of the window holds what `cpu::probes::gather_probe` gathers from where
/// `cpu::probes::relocate_probe` puts it, with the rays of its own seed (40, more than a probe's workgroup
/// has lanes), through the lighting volume and the
/// normals the GPU has (within float rounding, but for a few probes whose rays graze a voxel); the
/// irradiance volume holds each probe's faces in Bevy's layout (in f16); a probe in the floor moves out of
/// it; the room shows more light with the volume's intensity 1 than 0.
#[test]
fn the_probes_on_the_gpu_equal_their_cpu_twin_and_light_the_room() {
    let _gpu = gpu_lock();
    let (volume, gi) = small_room_settings();
    // 40 rays a probe: each of its 8 lanes (`cpu::probes::PROBE_LANES`) traces 5.
    let gi = VoxelGlobalIllumination { far_spacing: 0, rays: 40, ..gi };
    let mut app = lit_room(volume, gi.clone());
    run(&mut app, 12);
    let grid = grid_assets(&app).expect("a voxel grid");
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let window = app.world().resource::<bevy_hao::GiProbeWindow>().0.expect("a probe window");
    // Read back in the order the GPU wrote them, from one frame: the records, then what they were made from
    // (the scene is still: the lighting volume does not change any more).
    let (records, irradiance) = read_records_and_volume(&mut app, &assets);
    let (iw, ih, itexel) = (12, 16, 8);
    let (w, h, _, radiance) = read_image(&mut app, assets.radiance.clone(), 0);
    let [_, normal_image] = grid.attributes.clone().unwrap();
    let (_, _, _, normal) = read_image(&mut app, normal_image, 0);
    let voxels = read_trace_voxels(&mut app);
    let levels = trace_levels(&voxels);
    let windows = stats(&app).cascades.iter().map(|c| c.window_min).collect();
    let read = ReadVoxels { levels: &levels, windows, size: grid.texture_size, width: w, height: h, radiance, normal };
    assert_eq!(irradiance.len(), (iw * ih * 36 * itexel) as usize);
    let (mut agree, mut lit, mut moved) = (0, 0, 0);
    for i in 0..window.len() {
        let q = window.lattice(i);
        let slot = window.slot(q);
        let (faces, lattice, frames, seed) = record(&records, slot);
        assert_eq!((lattice, frames), (q, 1), "probe {q}: its record");
        let at = window.position(q);
        let p = relocate_probe(&levels, &read, at, window.spacing);
        moved += (p != at) as u32;
        let gathered_at = record_at(&records, slot);
        assert!(gathered_at.distance(p) < 1.0e-5, "probe {q}: gathered at {gathered_at}, the twin's {p}");
        let cpu = gather_probe(&levels, &read, p, window.spacing, gi.rays, probe_rotation(slot, seed));
        let scale = cpu.iter().chain(&faces).map(|f| f.max_element()).fold(1.0e-3, f32::max);
        let worst = (0..6).map(|k| (faces[k] - cpu[k]).abs().max_element()).fold(0.0, f32::max) / scale;
        agree += (worst < 1.0e-3) as u32;
        lit += (cpu.iter().any(|f| f.max_element() > 0.0)) as u32;
        // Bevy's layout: +x, -x in the first and second half of y; x, y, z faces in the thirds of z.
        let c = (q - window.min).as_uvec3();
        let texels = bevy_hao::cpu::far_probes::far_texel(Some(faces), window.edge_fade(q));
        for (k, face) in texels.iter().enumerate() {
            let texel = UVec3::new(c.x, c.y + (k as u32 & 1) * 8, c.z + (k as u32 >> 1) * 12);
            let t = (((texel.z * ih + texel.y) * iw + texel.x) * 8) as usize;
            let stored = Vec3::new(f16_at(&irradiance, t), f16_at(&irradiance, t + 2), f16_at(&irradiance, t + 4));
            // Within f16's range, faded toward the window's edges (`ProbeWindow::edge_fade`).
            let face = *face;
            let tolerance = face.abs() * 1.0e-3 + Vec3::splat(1.0e-4);
            assert!((stored - face).abs().cmple(tolerance).all(), "probe {q} face {k}: {stored} against {face}");
        }
    }
    println!("{} probes: {lit} see light, {agree} agree with the CPU twin, {moved} moved out of a voxel", window.len());
    assert!(lit * 2 > window.len(), "{lit} of {} probes see light", window.len());
    assert!(moved > 0, "no probe moved out of a voxel");
    assert!(agree * 100 >= window.len() * 98, "{agree} of {} probes agree", window.len());
    assert!(take_render_errors().is_empty());

    // Bevy's PBR applies the irradiance volume: with it the room's shadowed surfaces (the box's side, the
    // floor under the roof; dark with its intensity 0) take the light the sunlit floor and walls send them.
    let render = |gi: VoxelGlobalIllumination| {
        let mut app = lit_room(volume, gi);
        run(&mut app, 16);
        let target = app.world().resource::<Target>().0.clone();
        let (_, _, _, bytes) = read_image(&mut app, target, 2);
        if let Ok(dir) = std::env::var("GI_DUMP") {
            let name = format!("{dir}/room_{}.ppm", bytes.iter().map(|b| *b as u64).sum::<u64>());
            let mut ppm = format!("P6 {} {} 255\n", SIZE.x, SIZE.y).into_bytes();
            ppm.extend(bytes.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]));
            std::fs::write(name, ppm).unwrap();
        }
        assert!(take_render_errors().is_empty());
        bytes.chunks_exact(4).map(|p| p[0] as f32 + p[1] as f32 + p[2] as f32).collect::<Vec<f32>>()
    };
    // 8 m across, so that the volume reaches the floor 3 m under the camera.
    let counts = UVec3::splat(16);
    let with = render(VoxelGlobalIllumination { probe_counts: counts, far_spacing: 0, ..default() });
    let without = render(VoxelGlobalIllumination { intensity: 0.0, probe_counts: counts, far_spacing: 0, ..default() });
    let dark: Vec<usize> = (0..without.len()).filter(|&i| without[i] < 80.0).collect();
    let mean = |v: &[f32]| dark.iter().map(|&i| v[i]).sum::<f32>() / dark.len().max(1) as f32;
    println!(
        "{} shadowed pixels: mean {:.1} with the indirect light, {:.1} without",
        dark.len(),
        mean(&with),
        mean(&without)
    );
    assert!(dark.len() > 50, "{} shadowed pixels", dark.len());
    assert!(mean(&with) > 1.5 * mean(&without) + 10.0, "{} against {}", mean(&with), mean(&without));
}

/// The small room's voxels (two cascades of 64^3 from 0.125 m) and GI: 12 x 8 x 12 probes 0.5 m apart,
/// each updated every other frame with a history of one update, and far probes 1 m apart beside them.
fn small_room_settings() -> (VoxelVolume, VoxelGlobalIllumination) {
    let volume = VoxelVolume {
        bounds: VolumeBounds::FollowCamera { cascades: 2, cells: 64, finest_cell_size: 0.125 },
        ..default()
    };
    let gi = VoxelGlobalIllumination {
        probe_counts: UVec3::new(12, 8, 12),
        probe_spacing: 0.5,
        far_spacing: 2,
        far_probe_counts: UVec3::new(16, 12, 16),
        rays: 32,
        probe_frames: 2,
        accumulation_frames: 1,
        lighting_frames: 2,
        // The lighting volume changes no more once lit (the probe tests read it after the probes).
        bounce_feedback: 0.0,
        ..default()
    };
    assert!(gi.sanitized().1.is_empty(), "{:?}", gi.sanitized().1);
    (volume, gi)
}

/// The far probes on the GPU are written as their CPU twin says (`cpu::far_probes`): every far probe's
/// texel its faces faded toward the far window's edges; every near probe's texel `near_texel` of its own
/// faces, its fade and the far volume's faces at it, read from the far probes' records as Bevy samples
/// their volume (so that Bevy's mean of the two is the near light faded into the far one). The passes do
/// not need binding arrays (only Bevy's PBR, to apply two volumes): on a device without them (lavapipe)
/// the far probes are off, with a warning, and the test turns them on by hand.
#[test]
fn the_far_probes_on_the_gpu_are_written_as_their_cpu_twin() {
    use bevy_hao::cpu::far_probes::near_texel;
    use bevy_hao::cpu::probes::sample_faces;
    let _gpu = gpu_lock();
    let (volume, gi) = small_room_settings();
    let mut app = lit_room(volume, gi.clone());
    let support = app.world().resource::<bevy_hao::GiFarProbesSupport>().0.clone();
    println!("far probes on this device: {support:?}");
    app.insert_resource(bevy_hao::GiFarProbesSupport(Ok(())));
    run(&mut app, 12);
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let near = app.world().resource::<bevy_hao::GiProbeWindow>().0.expect("a probe window");
    let far = assets.far.clone().expect("far probes");
    let far_window = app.world().resource::<bevy_hao::GiFarProbeWindow>().0.expect("a far probe window");
    assert_eq!((far_window.counts, far_window.spacing), (UVec3::new(16, 12, 16), 1.0));
    let [near_records, near_volume, far_records, far_volume] = read_same_frame(
        &mut app,
        [
            Readback::buffer(assets.probe_records.clone()),
            Readback::texture(assets.irradiance.clone()),
            Readback::buffer(far.probe_records.clone()),
            Readback::texture(far.irradiance.clone()),
        ],
    );
    let (near_volume, far_volume) = (unpadded(&near_volume, near.counts.x), unpadded(&far_volume, far.probe_counts.x));
    let close = |stored: Vec3, want: Vec3| (stored - want).abs().cmple(want.abs() * 2.0e-3 + Vec3::splat(2.0e-3)).all();
    // The far probes' texels, as the twin has them from the records (in f32, as the GPU reads them).
    let far_faces = |w: UVec3| -> [Vec3; 6] {
        let q = far_window.min + w.as_ivec3();
        let (faces, lattice, frames, _) = record(&far_records, far_window.slot(q));
        let valid = lattice == q && frames > 0;
        bevy_hao::cpu::far_probes::far_texel(valid.then_some(faces), far_window.edge_fade(q))
    };
    let mut lit = 0;
    for i in 0..far_window.len() {
        let q = far_window.lattice(i);
        let c = (q - far_window.min).as_uvec3();
        let stored = stored_faces(&far_volume, far_window.counts, c);
        let want = far_faces(c);
        lit += want.iter().any(|f| f.max_element() > 0.0) as u32;
        for k in 0..6 {
            assert!(close(stored[k], want[k]), "far probe {q} face {k}: {} against {}", stored[k], want[k]);
        }
    }
    let mut faded = 0;
    for i in 0..near.len() {
        let q = near.lattice(i);
        let (own, lattice, frames, _) = record(&near_records, near.slot(q));
        assert_eq!((lattice, frames), (q, 1), "near probe {q}: its record");
        let at_far = sample_faces(&far_window, far_faces, near.position(q)).expect("near probes lie in the far window");
        let fade = near.edge_fade(q);
        faded += (fade < 1.0) as u32;
        let want = near_texel(own.map(|f| f.min(Vec3::splat(65504.0))), fade, Some(at_far));
        let stored = stored_faces(&near_volume, near.counts, (q - near.min).as_uvec3());
        for k in 0..6 {
            assert!(close(stored[k], want[k]), "near probe {q} face {k}: {} against {}", stored[k], want[k]);
        }
    }
    println!(
        "{} far probes, {lit} see light; {} near probes, {faded} faded into the far ones",
        far_window.len(),
        near.len()
    );
    assert!(lit * 4 > far_window.len() && faded > 0, "{lit} far probes see light, {faded} near ones fade");
    assert!(take_render_errors().is_empty());
}

/// Bevy's PBR applies the far probes' volume beside the near one: the room's shadowed surfaces, some
/// beyond the near window (6 x 4 x 6 m), show more light with the far probes than with the near ones
/// alone. Needs a device with binding arrays (Bevy 0.19 applies one irradiance volume without them; the
/// far probes are then off: `voxel_gi_turns_itself_off_where_it_cannot_run_and_takes_bad_settings`).
#[test]
#[ignore = "needs a device with binding arrays (not lavapipe): cargo test --release --test gpu_gi -- --ignored"]
fn bevys_pbr_applies_the_far_probes_beyond_the_near_window() {
    let _gpu = gpu_lock();
    let (volume, gi) = small_room_settings();
    let render = |gi: VoxelGlobalIllumination| {
        let mut app = lit_room(volume, gi);
        let support = &app.world().resource::<bevy_hao::GiFarProbesSupport>().0;
        assert!(support.is_ok(), "this test needs a device with binding arrays: {support:?}");
        run(&mut app, 16);
        let target = app.world().resource::<Target>().0.clone();
        let (_, _, _, bytes) = read_image(&mut app, target, 2);
        assert!(take_render_errors().is_empty());
        bytes.chunks_exact(4).map(|p| p[0] as f32 + p[1] as f32 + p[2] as f32).collect::<Vec<f32>>()
    };
    let with = render(gi.clone());
    let near_only = render(VoxelGlobalIllumination { far_spacing: 0, ..gi.clone() });
    let without = render(VoxelGlobalIllumination { intensity: 0.0, ..gi });
    let dark: Vec<usize> = (0..without.len()).filter(|&i| without[i] < 80.0).collect();
    let mean = |v: &[f32]| dark.iter().map(|&i| v[i]).sum::<f32>() / dark.len().max(1) as f32;
    println!(
        "{} shadowed pixels: mean {:.1} with the far probes, {:.1} with the near ones alone, {:.1} without GI",
        dark.len(),
        mean(&with),
        mean(&near_only),
        mean(&without)
    );
    assert!(dark.len() > 50, "{} shadowed pixels", dark.len());
    assert!(mean(&with) > mean(&near_only) + 5.0, "{} against {}", mean(&with), mean(&near_only));
}

/// Voxel GI where it cannot run, and with bad settings: on WebGPU's storage-binding limit (128 MiB) the
/// default cascades cannot keep their attributes, so GI is off (no lighting volume, no irradiance volume)
/// and the AO goes on; settings of zero, NaN and huge values are replaced and the frames go on; taking the
/// component off the camera takes the irradiance volume away. No validation error anywhere.
#[test]
fn voxel_gi_turns_itself_off_where_it_cannot_run_and_takes_bad_settings() {
    let _gpu = gpu_lock();
    let cascades = VoxelVolume::default();
    let mut app =
        app_on_device(webgpu_limits_with_storage(), || lit_room(cascades, VoxelGlobalIllumination::default()));
    run(&mut app, 6);
    let grid = grid_assets(&app).expect("the grid, without attributes");
    assert!(grid.attributes.is_none());
    assert!(app.world().get_resource::<bevy_hao::GiAssets>().is_none(), "no GI without attributes");
    let mut probes = app.world_mut().query::<&bevy_hao::GiIrradianceVolume>();
    assert_eq!(probes.iter(app.world()).count(), 0);
    assert!(take_render_errors().is_empty());
    drop(app);

    let bad = VoxelGlobalIllumination {
        intensity: f32::INFINITY,
        probe_spacing: f32::NAN,
        probe_counts: UVec3::new(0, 4, 100_000),
        far_spacing: 1000,
        far_probe_counts: UVec3::new(0, u32::MAX, 1),
        rays: 100_000,
        probe_frames: 0,
        accumulation_frames: 0,
        lighting_frames: 1000,
        bounce_feedback: -3.0,
    };
    let small = VoxelVolume {
        bounds: VolumeBounds::FollowCamera { cascades: 2, cells: 32, finest_cell_size: 0.125 },
        ..default()
    };
    let mut app = lit_room(small, bad);
    run(&mut app, 6);
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("GI with its settings replaced");
    assert_eq!(assets.probe_counts, UVec3::new(2, 4, 128));
    let mut probes = app.world_mut().query::<&bevy_hao::GiIrradianceVolume>();
    assert_eq!(probes.iter(app.world()).count(), 1);
    // The far probes, where the device blends volumes: 16 spacings apart, enough to hold the near window.
    let far_usable = app.world().resource::<bevy_hao::GiFarProbesSupport>().0.is_ok();
    assert_eq!(assets.far.as_ref().map(|f| f.factor), far_usable.then_some(16));
    let mut far_probes = app.world_mut().query::<&bevy_hao::GiFarIrradianceVolume>();
    assert_eq!(far_probes.iter(app.world()).count(), usize::from(far_usable));
    let mut cameras = app.world_mut().query_filtered::<Entity, With<VoxelGlobalIllumination>>();
    let camera = cameras.single(app.world()).unwrap();
    app.world_mut().entity_mut(camera).remove::<VoxelGlobalIllumination>();
    run(&mut app, 3);
    assert_eq!(probes.iter(app.world()).count(), 0, "the irradiance volume goes with the component");
    assert_eq!(far_probes.iter(app.world()).count(), 0, "the far one too");
    assert!(app.world().get_resource::<bevy_hao::GiAssets>().is_none());
    assert!(grid_assets(&app).is_some(), "the AO's grid stays");
    assert!(take_render_errors().is_empty());
}

/// The mean of every texel of the irradiance volume (its faces' irradiance over pi, rgb summed).
fn volume_mean(app: &mut App) -> f32 {
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let (_, _, texel, bytes) = read_image(app, assets.irradiance, 0);
    assert_eq!(texel, 8);
    let texels = bytes.len() / 8;
    (0..texels).map(|t| (0..3).map(|c| f16_at(&bytes, t * 8 + 2 * c)).sum::<f32>()).sum::<f32>() / texels as f32
}

/// The lit room with GI at the component's default frames (a 16 x 12 x 16 window; two cascades of 64^3 from
/// 0.125 m) and the given bounce feedback, and the frames its probes take to settle twice over.
fn room_at_default_frames(bounce_feedback: f32) -> (App, usize) {
    let volume = VoxelVolume {
        bounds: VolumeBounds::FollowCamera { cascades: 2, cells: 64, finest_cell_size: 0.125 },
        ..default()
    };
    let gi = VoxelGlobalIllumination { probe_counts: UVec3::new(16, 12, 16), bounce_feedback, ..default() };
    let converge = (20 + gi.lighting_frames + 2 * gi.accumulation_frames * gi.probe_frames) as usize;
    (lit_room(volume, gi), converge)
}

/// A light turned: the sun swung to another side of the room and made brighter, the indirect light is within
/// 10 % of its converged value 15 frames later (the goal), at the default frames.
#[test]
fn the_indirect_light_follows_a_light_turned_within_fifteen_frames() {
    let _gpu = gpu_lock();
    let (mut app, converge) = room_at_default_frames(VoxelGlobalIllumination::default().bounce_feedback);
    run(&mut app, converge);
    let before = volume_mean(&mut app);
    let mut suns = app.world_mut().query::<(&mut DirectionalLight, &mut Transform)>();
    for (mut light, mut transform) in suns.iter_mut(app.world_mut()) {
        light.illuminance *= 1.5;
        *transform = Transform::default().looking_to(Vec3::new(-0.6, -1.2, -0.5), Vec3::Y);
    }
    // The readback runs one frame: 14 here, the 15th in it.
    run(&mut app, 14);
    let after_15 = volume_mean(&mut app);
    run(&mut app, converge);
    let converged = volume_mean(&mut app);
    println!("the volume's mean: {before:.2} before, {after_15:.2} 15 frames after the turn, {converged:.2} converged");
    assert!((converged - before).abs() > 0.2 * before, "the turn changed the indirect light: {before} -> {converged}");
    assert!((after_15 - converged).abs() <= 0.1 * converged, "{after_15} against {converged}");
    assert!(take_render_errors().is_empty());
}

/// Puts the room's camera inside the room, under the roof's edge, looking at the sunlit floor: the probe
/// window and the voxels, which follow it, cover the room.
fn look_from_inside(app: &mut App) {
    run(app, 1);
    let mut cameras = app.world_mut().query_filtered::<&mut Transform, With<Camera3d>>();
    for mut t in cameras.iter_mut(app.world_mut()) {
        *t = Transform::from_xyz(0.0, -1.0, 0.0).looking_at(Vec3::new(1.5, -2.0, 0.5), Vec3::Y);
    }
}

/// The mean of the irradiance volume's faces (irradiance over pi, rgb summed) over the probes within the
/// box `lo`..`hi`.
fn region_mean(app: &mut App, lo: Vec3, hi: Vec3) -> f32 {
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let window = app.world().resource::<bevy_hao::GiProbeWindow>().0.expect("a probe window");
    let (_, _, texel, bytes) = read_image(app, assets.irradiance, 0);
    assert_eq!(texel, 8);
    let faces = region_faces(&bytes, &window, lo, hi);
    assert!(faces.len() >= 18 * 20, "{} probes in the region", faces.len() / 18);
    faces.iter().sum::<f32>() / (faces.len() / 3) as f32
}

/// Spawns a `DynamicOccluder` box of `size` at `at` into the app's world, grey.
fn spawn_dynamic_box(app: &mut App, size: Vec3, at: Vec3) -> Entity {
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(Cuboid::from_size(size));
    let material = app.world_mut().resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    app.world_mut()
        .spawn((Mesh3d(mesh), MeshMaterial3d(material), Transform::from_translation(at), DynamicOccluder))
        .id()
}

/// A box that slides back and forth by 5 cm every frame.
#[derive(Component)]
struct Jiggler(Vec3);

/// Probes near an occluder that moves keep the history its motion allows (`cpu::probes::moved_cap`): with
/// a 1 m box sliding 5 cm a frame (listed by the voxel grid as the box around it now and last frame, moved
/// by 5 cm), every probe's record on the GPU holds as many updates as the CPU twin's cap at its lattice
/// point says, after more updates than any cap: 2 inside the box (the 10 frames it takes to cross a
/// spacing, in updates every fourth frame), more farther as it covers less of their view, the default's 32
/// out of its reach.
#[test]
fn probes_near_a_moving_occluder_keep_the_history_its_motion_allows() {
    use bevy_hao::cpu::probes::moved_cap;
    use bevy_hao::cpu::temporal::MovedVoxels;
    let _gpu = gpu_lock();
    let (volume, _) = small_room_settings();
    let gi = VoxelGlobalIllumination {
        probe_counts: UVec3::new(12, 8, 12),
        far_spacing: 0,
        rays: 8,
        probe_frames: 4,
        accumulation_frames: 32,
        ..default()
    };
    let mut app = lit_room(volume, gi.clone());
    look_from_inside(&mut app);
    let at = Vec3::new(-1.0, -1.5, -1.25);
    let jiggler = spawn_dynamic_box(&mut app, Vec3::ONE, at);
    app.world_mut().entity_mut(jiggler).insert(Jiggler(at));
    app.add_systems(Update, |mut q: Query<(&mut Transform, &Jiggler)>| {
        for (mut t, j) in &mut q {
            t.translation = if t.translation == j.0 { j.0 + Vec3::new(0.05, 0.0, 0.0) } else { j.0 };
        }
    });
    run(&mut app, 20 + 40 * gi.probe_frames as usize);
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let window = app.world().resource::<bevy_hao::GiProbeWindow>().0.expect("a probe window");
    let (records, _) = read_records_and_volume(&mut app, &assets);
    let moved = [MovedVoxels { min: at - 0.5, max: at + Vec3::new(0.55, 0.5, 0.5), motion: 0.05 }];
    let (mut agree, mut within_one, mut short) = (0, 0, 0);
    for i in 0..window.len() {
        let q = window.lattice(i);
        let (_, lattice, frames, _) = record(&records, window.slot(q));
        assert_eq!(lattice, q, "probe {q}: its record");
        let cap = moved_cap(window.position(q), window.spacing, gi.probe_frames, &moved, gi.accumulation_frames);
        agree += (frames == cap) as u32;
        within_one += (frames.abs_diff(cap) <= 1) as u32;
        short += (cap < gi.accumulation_frames) as u32;
    }
    println!("{} probes: {short} near the box with a shorter history, {agree} agree with the CPU twin", window.len());
    assert!(short >= 80 && short < window.len(), "{short} of {} probes near the box", window.len());
    assert_eq!(within_one, window.len(), "every probe's history within an update of the twin's cap");
    assert!(agree * 100 >= window.len() * 98, "{agree} of {} probes agree", window.len());
    assert!(take_render_errors().is_empty());
}

/// An occluder moved: a panel the size of the sunlit half of the room jumped from the roof's shade to over
/// the sunlit floor, the indirect light is within 10 % of its converged value 15 frames later, as for a
/// light turned (the probes near it keep only their last update while it is listed as moved), at the
/// default frames.
#[test]
fn the_indirect_light_follows_an_occluder_moved_within_fifteen_frames() {
    let _gpu = gpu_lock();
    let (mut app, converge) = room_at_default_frames(VoxelGlobalIllumination::default().bounce_feedback);
    look_from_inside(&mut app);
    // In the roof's shade, then over the sunlit floor, half a metre under the roof.
    let panel = spawn_dynamic_box(&mut app, Vec3::new(3.0, 0.1, 6.0), Vec3::new(-1.5, -0.5, 0.0));
    run(&mut app, converge);
    // The probes between the sunlit floor and where the panel comes.
    let (lo, hi) = (Vec3::new(0.25, -1.75, -2.5), Vec3::new(2.75, -0.75, 2.5));
    let before = region_mean(&mut app, lo, hi);
    app.world_mut().get_mut::<Transform>(panel).unwrap().translation = Vec3::new(1.5, -0.5, 0.0);
    // The readback runs one frame: 14 here, the 15th in it.
    run(&mut app, 14);
    let after_15 = region_mean(&mut app, lo, hi);
    run(&mut app, converge);
    let converged = region_mean(&mut app, lo, hi);
    println!("under the panel: {before:.2} before, {after_15:.2} 15 frames after the move, {converged:.2} converged");
    assert!((converged - before).abs() > 0.2 * before, "the move changed the indirect light: {before} -> {converged}");
    assert!((after_15 - converged).abs() <= 0.1 * converged, "{after_15} against {converged}");
    assert!(take_render_errors().is_empty());
}

/// A ball rolling back and forth along x over the sunlit floor, 2.5 cm a frame.
#[derive(Component)]
struct Roller {
    from: f32,
    to: f32,
    step: f32,
}

/// The probes' faces (irradiance over pi, rgb) within `lo`..`hi` of an irradiance volume's bytes.
fn region_faces(bytes: &[u8], window: &bevy_hao::cpu::probes::ProbeWindow, lo: Vec3, hi: Vec3) -> Vec<f32> {
    let c = window.counts;
    let row = c.x as usize * 8;
    let mut out = Vec::new();
    for i in 0..window.len() {
        let q = window.lattice(i);
        let p = window.position(q);
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            continue;
        }
        let t = (q - window.min).as_uvec3();
        for k in 0..6u32 {
            let (y, z) = (t.y + (k & 1) * c.y, t.z + (k >> 1) * c.z);
            let at = (z as usize * 2 * c.y as usize + y as usize) * row + t.x as usize * 8;
            out.extend((0..3).map(|j| f16_at(bytes, at + 2 * j)));
        }
    }
    out
}

/// Around a ball rolling over the sunlit floor, the probes follow it without flicker
/// (`cpu::probes::moved_cap` keeps them a history as long as the little the ball changes in their view
/// allows), over the probes within a metre of its path: their change from frame to frame at most 0.4 % of
/// their light, and their light in the last of 32 frames read in motion at most 2 times as far from the
/// same pose held still and converged as two still, converged frames far apart are from each other. (A cap
/// of the updates it takes the ball to cross their distance alone, short of its share of their view:
/// 0.66 % and 2.5 times. The bar for the AO in motion, 1.25 times, is not met: 1.73 times here,
/// 1.45 with no cap at all, their history's lag over its 128 frames.) One bounce, so that what is measured
/// is the probes' histories: with the default bounce feedback the light the voxels send on follows the
/// ball as slowly as its loop runs, 0.18 % and 2.26 times (docs/figures.md, *Further bounces*).
#[test]
fn the_probes_around_a_rolling_ball_follow_it() {
    let _gpu = gpu_lock();
    let (lo, hi) = (Vec3::new(0.0, -2.0, -0.5), Vec3::new(2.5, -1.0, 1.5));
    let (mut app, converge) = room_at_default_frames(0.0);
    look_from_inside(&mut app);
    let ball = {
        let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(Sphere::new(0.25).mesh().uv(32, 16));
        let material = app.world_mut().resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
        app.world_mut()
            .spawn((
                Mesh3d(mesh),
                MeshMaterial3d(material),
                Transform::from_xyz(0.5, -1.75, 0.5),
                DynamicOccluder,
                Roller { from: 0.5, to: 2.0, step: 0.025 },
            ))
            .id()
    };
    app.add_systems(Update, |mut q: Query<(&mut Transform, &mut Roller)>| {
        for (mut t, mut r) in &mut q {
            if !(r.from..=r.to).contains(&(t.translation.x + r.step)) {
                r.step = -r.step;
            }
            t.translation.x += r.step;
        }
    });
    run(&mut app, converge);
    let assets = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let window = app.world().resource::<bevy_hao::GiProbeWindow>().0.expect("a probe window");
    let frames = read_frames(&mut app, std::slice::from_ref(&assets.irradiance), 32, |app, k| {
        if k == 31 {
            app.world_mut().entity_mut(ball).remove::<Roller>();
        }
    });
    let faces: Vec<Vec<f32>> = frames[0].iter().map(|b| region_faces(b, &window, lo, hi)).collect();
    let n = faces[0].len();
    let mean = faces.iter().flatten().sum::<f32>() / (n * faces.len()) as f32;
    let change = faces.windows(2).map(|w| (0..n).map(|i| (w[1][i] - w[0][i]).abs()).sum::<f32>()).sum::<f32>()
        / (n * (faces.len() - 1)) as f32;
    // The last frame's pose, held still (the ball stays where it stopped) and converged.
    run(&mut app, converge);
    let (_, _, _, still) = read_image(&mut app, assets.irradiance.clone(), 0);
    let still = region_faces(&still, &window, lo, hi);
    let last = faces.last().unwrap();
    let error = (0..n).map(|i| (last[i] - still[i]).abs()).sum::<f32>() / n as f32;
    let still_mean = still.iter().sum::<f32>() / n as f32;
    // The same pose again, a history later: how far apart two still, converged frames are.
    run(&mut app, converge);
    let (_, _, _, again) = read_image(&mut app, assets.irradiance.clone(), 0);
    let again = region_faces(&again, &window, lo, hi);
    let floor = (0..n).map(|i| (again[i] - still[i]).abs()).sum::<f32>() / n as f32;
    println!(
        "{} probes near the path: mean {mean:.2} in motion, {still_mean:.2} still; change a frame {change:.3} \
         ({:.2} % of the mean); the last frame against it still and converged {error:.3} ({:.2} %), two still \
         frames {floor:.3} ({:.2} %): {:.2}x",
        n / 18,
        100.0 * change / mean,
        100.0 * error / still_mean,
        100.0 * floor / still_mean,
        error / floor
    );
    assert!(change <= 0.004 * mean, "a change of {change} a frame in {mean}");
    assert!(floor > 0.0 && error <= 2.0 * floor, "in motion {error} against still {floor}");
    assert!(take_render_errors().is_empty());
}
