//! The binvox format (Patrick Min's `binvox`, read by viewvox, Blender add-ons, trimesh, binvox-rw...).
//!
//! ```text
//! #binvox 1
//! dim D D D
//! translate tx ty tz
//! scale s
//! data
//! <run-length pairs of bytes: value (0 or 1), count (1..=255)>
//! ```
//!
//! The grid is a cube of `D^3` voxels in binvox order: x slowest, then z, y fastest (index
//! `x * D * D + z * D + y`). Voxel `(x, y, z)` covers `translate + (x, y, z) * scale / D` to one step more.
//! A [`VoxelOccupancy`] with per-axis dimensions is written with `D` = its longest axis, padded with empty
//! voxels, `translate` = the grid origin and `scale` = `D * cell_size`.

use bevy_hao::cpu::{VoxelGrid, VoxelOccupancy};
use glam::{UVec3, Vec3};
use std::io::{self, BufRead, Write};

/// A binvox grid as read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct Binvox {
    /// Voxels per axis.
    pub dim: UVec3,
    /// World position of the grid's min corner.
    pub translate: Vec3,
    /// World size of the grid's longest axis.
    pub scale: f32,
    /// Occupancy in binvox order (x slowest, then z, y fastest).
    pub voxels: Vec<bool>,
}

impl Binvox {
    /// Whether voxel `(x, y, z)` is set.
    pub fn get(&self, x: u32, y: u32, z: u32) -> bool {
        if x >= self.dim.x || y >= self.dim.y || z >= self.dim.z {
            return false;
        }
        let (dy, dz) = (self.dim.y as usize, self.dim.z as usize);
        self.voxels.get(x as usize * dz * dy + z as usize * dy + y as usize).copied().unwrap_or(false)
    }

    /// Number of set voxels.
    pub fn set_count(&self) -> usize {
        self.voxels.iter().filter(|v| **v).count()
    }

    /// The voxels as an occupancy grid on the cubic grid the file describes.
    pub fn to_occupancy(&self) -> Result<VoxelOccupancy, bevy_hao::cpu::GridError> {
        let cell = self.scale / self.dim.max_element() as f32;
        let grid = VoxelGrid::new(self.translate, cell, self.dim)?;
        let occ = VoxelOccupancy::new(grid, false);
        for x in 0..self.dim.x {
            for z in 0..self.dim.z {
                for y in 0..self.dim.y {
                    if self.get(x, y, z) {
                        occ.set(UVec3::new(x, y, z));
                    }
                }
            }
        }
        Ok(occ)
    }
}

/// Writes an occupancy grid as binvox (see the module docs for the layout).
pub fn write_binvox(occ: &VoxelOccupancy, out: &mut impl Write) -> io::Result<()> {
    let grid = occ.grid();
    let d = grid.dims.max_element();
    writeln!(out, "#binvox 1")?;
    writeln!(out, "dim {d} {d} {d}")?;
    writeln!(out, "translate {} {} {}", grid.origin.x, grid.origin.y, grid.origin.z)?;
    writeln!(out, "scale {}", d as f32 * grid.cell_size)?;
    writeln!(out, "data")?;
    let mut run_value = 0u8;
    let mut run_len = 0u8;
    let mut bytes = Vec::with_capacity(1 << 16);
    let mut push = |value: u8, bytes: &mut Vec<u8>| {
        if value == run_value && run_len < 255 {
            run_len += 1;
        } else {
            if run_len > 0 {
                bytes.extend_from_slice(&[run_value, run_len]);
            }
            run_value = value;
            run_len = 1;
        }
    };
    for x in 0..d {
        for z in 0..d {
            for y in 0..d {
                let inside = x < grid.dims.x && y < grid.dims.y && z < grid.dims.z;
                push(u8::from(inside && occ.is_set(UVec3::new(x, y, z))), &mut bytes);
            }
            if bytes.len() >= 1 << 16 {
                out.write_all(&bytes)?;
                bytes.clear();
            }
        }
    }
    if run_len > 0 {
        bytes.extend_from_slice(&[run_value, run_len]);
    }
    out.write_all(&bytes)
}

/// Largest `dim` along an axis [`read_binvox`] accepts.
pub const MAX_BINVOX_DIM: u32 = 4096;
/// Most voxels [`read_binvox`] accepts (1 GiB of booleans).
pub const MAX_BINVOX_VOXELS: u64 = 1 << 30;

/// Reads a binvox file. The header is validated (whole dims from 1 to [`MAX_BINVOX_DIM`], at most
/// [`MAX_BINVOX_VOXELS`], finite translate and positive scale) before anything is allocated, and the runs are
/// stopped at the total the header declares.
pub fn read_binvox(input: &mut impl BufRead) -> io::Result<Binvox> {
    let bad = |msg: String| io::Error::new(io::ErrorKind::InvalidData, msg);
    let mut line = String::new();
    input.read_line(&mut line)?;
    if !line.starts_with("#binvox") {
        return Err(bad(format!("not a binvox file (first line {line:?})")));
    }
    let (mut dim, mut translate, mut scale) = (None, Vec3::ZERO, 1.0f32);
    loop {
        line.clear();
        if input.read_line(&mut line)? == 0 {
            return Err(bad("binvox header ends before 'data'".into()));
        }
        let mut words = line.split_whitespace();
        let nums = |words: std::str::SplitWhitespace| -> io::Result<Vec<f32>> {
            words.map(|w| w.parse::<f32>().map_err(|e| bad(format!("bad number {w:?}: {e}")))).collect()
        };
        match words.next() {
            Some("dim") => {
                let v = nums(words)?;
                // Whole numbers from 1 to MAX_BINVOX_DIM (NaN fails the range test).
                if v.len() != 3 || v.iter().any(|x| !((1.0..=MAX_BINVOX_DIM as f32).contains(x) && x.fract() == 0.0)) {
                    return Err(bad(format!(
                        "bad dim line {:?} (three whole numbers from 1 to {MAX_BINVOX_DIM} expected)",
                        line.trim_end()
                    )));
                }
                dim = Some(UVec3::new(v[0] as u32, v[1] as u32, v[2] as u32));
            }
            Some("translate") => {
                let v = nums(words)?;
                if v.len() != 3 {
                    return Err(bad(format!("bad translate line {line:?}")));
                }
                translate = Vec3::new(v[0], v[1], v[2]);
                if !translate.is_finite() {
                    return Err(bad(format!("bad translate line {:?}", line.trim_end())));
                }
            }
            Some("scale") => {
                scale = *nums(words)?.first().ok_or_else(|| bad("empty scale".into()))?;
                if !(scale.is_finite() && scale > 0.0) {
                    return Err(bad(format!("bad scale line {:?}", line.trim_end())));
                }
            }
            Some("data") => break,
            _ => {}
        }
    }
    let dim = dim.ok_or_else(|| bad("binvox header without dim".into()))?;
    let total = dim.x as u64 * dim.y as u64 * dim.z as u64;
    if total > MAX_BINVOX_VOXELS {
        return Err(bad(format!("binvox dim {dim} holds {total} voxels, over the limit of {MAX_BINVOX_VOXELS}")));
    }
    let total = total as usize;
    // The runs are read as they come and stopped at the declared total, so memory never exceeds it; nothing
    // is reserved up front beyond a megabyte (a 30-byte header may declare a gigabyte it does not hold).
    let mut voxels = Vec::with_capacity(total.min(1 << 20));
    let mut pair = [0u8; 2];
    loop {
        match input.read_exact(&mut pair) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => break,
            Err(e) => return Err(e),
        }
        let run = pair[1] as usize;
        if voxels.len() + run > total {
            return Err(bad(format!("binvox data runs past the {total} voxels its dim declares")));
        }
        voxels.extend(std::iter::repeat_n(pair[0] != 0, run));
    }
    if voxels.len() != total {
        return Err(bad(format!("binvox data holds {} voxels, dim says {total}", voxels.len())));
    }
    Ok(Binvox { dim, translate, scale, voxels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn malformed_headers_and_data_are_refused_before_allocating() {
        let read = |bytes: &[u8]| read_binvox(&mut std::io::Cursor::new(bytes.to_vec()));
        for header in [
            "#binvox 1\ndim 100000 100000 100000\ndata\n",
            "#binvox 1\ndim NaN 4 4\ndata\n",
            "#binvox 1\ndim 2.5 4 4\ndata\n",
            "#binvox 1\ndim 0 4 4\ndata\n",
            "#binvox 1\ndim 4 4\ndata\n",
            "#binvox 1\ndim 4 4 4\nscale inf\ndata\n",
            "#binvox 1\ndim 4 4 4\ntranslate NaN 0 0\ndata\n",
            "#binvox 1\ndim 4 4 4\n",
            "not binvox",
        ] {
            assert!(read(header.as_bytes()).is_err(), "{header:?} was accepted");
        }
        // Runs past the declared total, and too few voxels.
        let mut past = b"#binvox 1\ndim 2 2 2\ndata\n".to_vec();
        past.extend_from_slice(&[1, 255, 1, 255]);
        assert!(read(&past).is_err());
        let mut short = b"#binvox 1\ndim 2 2 2\ndata\n".to_vec();
        short.extend_from_slice(&[1, 7]);
        assert!(read(&short).is_err());
        let mut ok = b"#binvox 1\ndim 2 2 2\ndata\n".to_vec();
        ok.extend_from_slice(&[1, 3, 0, 5]);
        let b = read(&ok).unwrap();
        assert_eq!(b.set_count(), 3);
        assert!(!b.get(9, 9, 9), "out of range reads as empty");
    }
}
