//! `map_index.bin`: the map's block boxes as they are (they only grow
//! between rebuilds, and culling reads them, so a continued run needs the
//! same ones) and the spatial order's sorted runs. Little-endian: `u64`
//! block count, per block 6 `f32` (box min xyz, max xyz; world frame,
//! metres) and `u32` newest and oldest `last_seen` frame; `u64` run count,
//! per run `u64` start and end (surfel indices).

use super::binary::{alloc, put_f32, put_u32, put_u64, LeReader};
use super::SessionError;
use crate::fusion::chunk_bounds::{BlockBox, BLOCK};
use crate::fusion::SurfelMap;
use glam::Vec3;
use std::io::{Read, Write};
use std::ops::Range;

const NAME: &str = "map_index.bin";

/// Writes the block boxes of `map` and the sorted `runs`.
pub(super) fn write_map_index(
    out: &mut dyn Write,
    map: &SurfelMap,
    runs: &[Range<usize>],
) -> std::io::Result<()> {
    let blocks = map.bounds().len();
    put_u64(out, blocks as u64)?;
    for b in (0..blocks).filter_map(|b| map.bounds().block(b)) {
        for v in [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z] {
            put_f32(out, v)?;
        }
        put_u32(out, b.newest)?;
        put_u32(out, b.oldest)?;
    }
    put_u64(out, runs.len() as u64)?;
    for r in runs {
        put_u64(out, r.start as u64)?;
        put_u64(out, r.end as u64)?;
    }
    Ok(())
}

/// Block boxes and sorted runs.
pub(super) type MapIndex = (Vec<BlockBox>, Vec<Range<usize>>);

/// Reads the index of a map of `surfels` slots.
pub(super) fn read_map_index(input: impl Read, surfels: usize) -> Result<MapIndex, SessionError> {
    let mut r = LeReader::new(input, NAME);
    let count = r.count(surfels.div_ceil(BLOCK), "block boxes")?;
    let mut blocks = alloc(count, NAME)?;
    for _ in 0..count {
        let mut v = [0.0f32; 6];
        for x in &mut v {
            *x = r.f32()?;
        }
        blocks.push(BlockBox {
            min: Vec3::new(v[0], v[1], v[2]),
            max: Vec3::new(v[3], v[4], v[5]),
            newest: r.u32()?,
            oldest: r.u32()?,
        });
    }
    let count = r.count(surfels, "sorted runs")?;
    let mut runs = alloc(count, NAME)?;
    for _ in 0..count {
        runs.push(r.count(surfels, "run start")?..r.count(surfels, "run end")?);
    }
    r.finish()?;
    Ok((blocks, runs))
}
