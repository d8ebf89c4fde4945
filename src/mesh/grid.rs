//! The sparse voxel grid: blocks of 8x8x8 voxels, created only where a
//! surfel's kernel reaches, holding the signed distance, the summed kernel
//! weight and the colour at each voxel (lattice point `voxel * size`).

use std::collections::HashMap;

use glam::{IVec3, Vec3};
use rayon::prelude::*;

use super::{MeshConfig, MeshError};
use crate::fusion::SurfelMap;

/// Voxels along a block edge.
pub(super) const B: i32 = 8;
/// Voxels in a block.
pub(super) const BV: usize = 512;
/// Block coordinates must lie within +-this (21 bits each in a packed key).
const KEY_LIMIT: i32 = (1 << 20) - 2;
/// Confidence at which a surfel has its full kernel weight: a surfel's
/// position averages about this many measurements by then.
const FULL_WEIGHT_CONFIDENCE: f32 = 20.0;
/// Progress calls per parallel stage.
const BATCHES: usize = 24;
/// Voxel flag: the summed kernel weight reached `MeshConfig::min_weight`.
pub(super) const OBSERVED: u8 = 1;
/// Voxel flag: a surfel centre lies within `MeshConfig::max_gap_voxels`.
pub(super) const NEAR: u8 = 2;
/// No block / no vertex.
pub(super) const NONE: u32 = u32::MAX;

/// A block key packed into one integer (sorting by it groups blocks by z
/// slab, then y row).
pub(super) fn pack(k: IVec3) -> u64 {
    let bias = |v: i32| (v + (1 << 20)) as u64 & 0x1f_ffff;
    (bias(k.x) << 42) | (bias(k.y) << 21) | bias(k.z)
}

/// Index of a neighbour offset `d` (each component -1..=1) in a block's
/// table of 27 neighbours.
#[inline(always)]
pub(super) fn neighbour_slot(d: IVec3) -> usize {
    ((d.x + 1) + 3 * (d.y + 1) + 9 * (d.z + 1)) as usize
}

/// Index of local voxel `v` (each component 0..8) inside a block.
#[inline(always)]
pub(super) fn local_index(v: IVec3) -> usize {
    (v.x + B * (v.y + B * v.z)) as usize
}

/// The sparse grid and the scratch of building it.
#[derive(Debug, Default)]
pub(super) struct Grid {
    /// Voxel edge, metres.
    pub(super) voxel: f32,
    /// Selected surfels as (packed block key, surfel index), sorted.
    sorted: Vec<(u64, u32)>,
    /// Packed block key -> range in `sorted`.
    buckets: HashMap<u64, (u32, u32)>,
    /// Key of each block, in block order (sorted by packed key).
    pub(super) keys: Vec<IVec3>,
    /// Packed block key -> block index.
    index: HashMap<u64, u32>,
    /// Per block, the block index of each of its 27 neighbours (`NONE` if absent).
    pub(super) neighbours: Vec<[u32; 27]>,
    /// Signed distance per voxel, metres (positive on the side the normals point to).
    pub(super) sdf: Vec<f32>,
    /// Colour per voxel, RGB8, and in the fourth byte the flags
    /// [`OBSERVED`] and [`NEAR`] (one array instead of three: the grid is
    /// most of the meshing's memory).
    pub(super) colour: Vec<[u8; 4]>,
    /// Per cell (named by its lowest voxel), the index of its mesh vertex or `NONE`.
    pub(super) cell_vertex: Vec<u32>,
    /// Old vertex index -> new, when unused vertices are dropped.
    pub(super) remap: Vec<u32>,
}

/// A surfel fit for meshing: finite, unit normal, sane radius.
fn usable(map: &SurfelMap, i: usize, config: &MeshConfig) -> bool {
    let c = map.confidences()[i];
    let r = map.radii()[i];
    let n = map.normals()[i];
    c >= config.min_confidence
        && c.is_finite()
        && r.is_finite()
        && r > 0.0
        && map.positions()[i].is_finite()
        && n.is_finite()
        && (n.length_squared() - 1.0).abs() < 0.1
}

impl Grid {
    pub(super) fn block_count(&self) -> usize {
        self.keys.len()
    }

    pub(super) fn heap_bytes(&self) -> usize {
        use std::mem::size_of;
        self.sorted.capacity() * size_of::<(u64, u32)>()
            + (self.buckets.capacity() + self.index.capacity()) * (size_of::<u64>() + 8 + 1)
            + self.keys.capacity() * size_of::<IVec3>()
            + self.neighbours.capacity() * size_of::<[u32; 27]>()
            + self.sdf.capacity() * 4
            + self.colour.capacity() * 4
            + self.cell_vertex.capacity() * 4
            + self.remap.capacity() * 4
    }

    /// Builds the grid of `map` (`self.voxel` set from `config`). Returns the
    /// numbers of surfels used and skipped.
    ///
    /// Phases, in order: `bucket_surfels`, `allocate_blocks`,
    /// `link_neighbours`, `splat_blocks`.
    pub(super) fn fill(
        &mut self,
        map: &SurfelMap,
        config: &MeshConfig,
        progress: &mut dyn FnMut(f32),
    ) -> Result<(usize, usize), MeshError> {
        let voxel = config.voxel_size_m;
        self.voxel = voxel;
        let n = map.common_len();
        let used = self.bucket_surfels(map, config);
        progress(0.05);
        self.allocate_blocks(map, config)?;
        self.link_neighbours();
        progress(0.1);
        self.splat_blocks(map, config, progress);
        Ok((used, n - used))
    }

    /// Reach of a surfel's kernel from its centre, metres.
    fn reach_m(config: &MeshConfig) -> f32 {
        config.support_voxels.max(config.tangential_voxels) * config.voxel_size_m
    }

    /// Groups the usable surfels by the block their centre lies in
    /// (`self.sorted`, `self.buckets`); returns how many were used.
    fn bucket_surfels(&mut self, map: &SurfelMap, config: &MeshConfig) -> usize {
        let block_m = config.voxel_size_m * B as f32;
        self.sorted.clear();
        let limit = KEY_LIMIT as f32;
        for i in 0..map.common_len() {
            if !usable(map, i, config) {
                continue;
            }
            let b = (map.positions()[i] / block_m).floor();
            if b.abs().max_element() >= limit {
                continue;
            }
            self.sorted.push((pack(b.as_ivec3()), i as u32));
        }
        let used = self.sorted.len();
        self.sorted.par_sort_unstable();
        self.buckets.clear();
        let mut start = 0;
        while start < self.sorted.len() {
            let key = self.sorted[start].0;
            let mut end = start + 1;
            while end < self.sorted.len() && self.sorted[end].0 == key {
                end += 1;
            }
            self.buckets.insert(key, (start as u32, end as u32));
            start = end;
        }
        used
    }

    /// Creates every block some surfel's kernel reaches (the box of each
    /// bucket's centres grown by the reach), in packed-key order
    /// (`self.keys`, `self.index`); refuses more than `config.max_blocks`.
    fn allocate_blocks(&mut self, map: &SurfelMap, config: &MeshConfig) -> Result<(), MeshError> {
        let reach = Self::reach_m(config);
        let block_m = config.voxel_size_m * B as f32;
        self.index.clear();
        self.keys.clear();
        // Buckets in key order (not the hash map's): where `max_blocks` stops
        // the count, and so the error, is the same on every run.
        for bucket in self.sorted.chunk_by(|a, b| a.0 == b.0) {
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for &(_, i) in bucket {
                let p = map.positions()[i as usize];
                lo = lo.min(p);
                hi = hi.max(p);
            }
            let (blo, bhi) = (
                ((lo - reach) / block_m).floor().as_ivec3(),
                ((hi + reach) / block_m).floor().as_ivec3(),
            );
            for z in blo.z..=bhi.z {
                for y in blo.y..=bhi.y {
                    for x in blo.x..=bhi.x {
                        let k = IVec3::new(x, y, z);
                        if self.index.insert(pack(k), 0).is_none() {
                            self.keys.push(k);
                        }
                    }
                }
            }
            if self.keys.len() > config.max_blocks {
                break;
            }
        }
        if self.keys.len() > config.max_blocks {
            let blocks = self.keys.len();
            self.clear_blocks();
            return Err(MeshError::TooLarge {
                blocks,
                max: config.max_blocks,
                voxel_size_m: config.voxel_size_m,
            });
        }
        // Sorted, so that the output does not depend on hash order.
        self.keys.sort_unstable_by_key(|&k| pack(k));
        for (b, &k) in self.keys.iter().enumerate() {
            self.index.insert(pack(k), b as u32);
        }
        Ok(())
    }

    /// Fills each block's table of its 27 neighbours' block indices
    /// (`self.neighbours`).
    fn link_neighbours(&mut self) {
        self.neighbours.clear();
        for &k in &self.keys {
            let mut table = [NONE; 27];
            for (slot, t) in table.iter_mut().enumerate() {
                let s = slot as i32;
                let d = IVec3::new(s % 3 - 1, (s / 3) % 3 - 1, s / 9 - 1);
                *t = self.index.get(&pack(k + d)).copied().unwrap_or(NONE);
            }
            self.neighbours.push(table);
        }
    }

    /// Distance, weight and colour of every voxel, block by block
    /// (`self.sdf`, `self.colour`; a block gathers the surfels of its 27
    /// neighbour buckets: no two threads write one voxel). Reports progress
    /// from 0.1 to 1.
    fn splat_blocks(
        &mut self,
        map: &SurfelMap,
        config: &MeshConfig,
        progress: &mut dyn FnMut(f32),
    ) {
        let voxel = config.voxel_size_m;
        let blocks = self.keys.len();
        self.sdf.clear();
        self.sdf.resize(blocks * BV, 0.0);
        self.colour.clear();
        self.colour.resize(blocks * BV, [0; 4]);
        let batch = blocks.div_ceil(BATCHES).max(1);
        let splat = Splat {
            map,
            sorted: &self.sorted,
            buckets: &self.buckets,
            voxel,
            reach: Self::reach_m(config),
            normal_reach: config.support_voxels * voxel,
            tangential_reach: config.tangential_voxels * voxel,
            min_weight: config.min_weight,
            max_gap2: (config.max_gap_voxels * voxel).powi(2),
        };
        for (n_done, ((keys, sdf), colour)) in self
            .keys
            .chunks(batch)
            .zip(self.sdf.chunks_mut(batch * BV))
            .zip(self.colour.chunks_mut(batch * BV))
            .enumerate()
        {
            keys.par_iter()
                .zip(sdf.par_chunks_mut(BV))
                .zip(colour.par_chunks_mut(BV))
                .for_each_init(
                    || vec![[0.0f32; 6]; BV],
                    |acc, ((&key, sdf), colour)| {
                        splat.block_into(key, acc, sdf, colour);
                    },
                );
            progress(0.1 + 0.9 * ((n_done + 1) * batch).min(blocks) as f32 / blocks as f32);
        }
    }

    fn clear_blocks(&mut self) {
        self.keys.clear();
        self.index.clear();
        self.neighbours.clear();
        self.sdf.clear();
        self.colour.clear();
        self.cell_vertex.clear();
    }
}

/// What filling one block reads.
struct Splat<'a> {
    map: &'a SurfelMap,
    sorted: &'a [(u64, u32)],
    buckets: &'a HashMap<u64, (u32, u32)>,
    voxel: f32,
    reach: f32,
    normal_reach: f32,
    tangential_reach: f32,
    min_weight: f32,
    max_gap2: f32,
}

impl Splat<'_> {
    /// Fills one block: `acc` is scratch (per voxel: weighted distance,
    /// weight, weighted r, g, b, squared distance to the nearest centre).
    fn block_into(
        &self,
        key: IVec3,
        acc: &mut [[f32; 6]],
        sdf: &mut [f32],
        colour: &mut [[u8; 4]],
    ) {
        acc.fill([0.0, 0.0, 0.0, 0.0, 0.0, f32::INFINITY]);
        let origin = key * B;
        // Positions relative to the block's first voxel keep f32 precise
        // far from the world origin.
        let origin_m = origin.as_vec3() * self.voxel;
        let inv_voxel = 1.0 / self.voxel;
        let inv_normal2 = 1.0 / (self.normal_reach * self.normal_reach);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(&(start, end)) = self.buckets.get(&pack(key + IVec3::new(dx, dy, dz)))
                    else {
                        continue;
                    };
                    for &(_, i) in &self.sorted[start as usize..end as usize] {
                        let i = i as usize;
                        let p = self.map.positions()[i] - origin_m;
                        let lo = ((p - self.reach) * inv_voxel)
                            .ceil()
                            .as_ivec3()
                            .max(IVec3::ZERO);
                        let hi = ((p + self.reach) * inv_voxel)
                            .floor()
                            .as_ivec3()
                            .min(IVec3::splat(B - 1));
                        if lo.cmpgt(hi).any() {
                            continue;
                        }
                        let n = self.map.normals()[i];
                        // A wide disk (far or oblique view) reaches further
                        // along the surface.
                        let rt = self
                            .tangential_reach
                            .max(self.map.radii()[i].min(self.reach));
                        let inv_tangential2 = 1.0 / (rt * rt);
                        let c = (self.map.confidences()[i] / FULL_WEIGHT_CONFIDENCE).min(1.0);
                        let rgb = self.map.colours()[i];
                        let rgb = [f32::from(rgb[0]), f32::from(rgb[1]), f32::from(rgb[2])];
                        for z in lo.z..=hi.z {
                            for y in lo.y..=hi.y {
                                let row = local_index(IVec3::new(0, y, z));
                                for x in lo.x..=hi.x {
                                    let d = IVec3::new(x, y, z).as_vec3() * self.voxel - p;
                                    let along = n.dot(d);
                                    let across2 = d.length_squared() - along * along;
                                    // Elliptic reach: the distance field
                                    // needs depth across the surface (a
                                    // crossed cell's corners lie up to 1.7
                                    // voxels off it), not width along it,
                                    // where it would run past the surface's
                                    // edge.
                                    let q = along * along * inv_normal2 + across2 * inv_tangential2;
                                    if q >= 1.0 {
                                        continue;
                                    }
                                    // Wendland-like: smooth, zero at the reach.
                                    let k = 1.0 - q;
                                    let w = c * k * k;
                                    let a = &mut acc[row + x as usize];
                                    a[5] = a[5].min(d.length_squared());
                                    a[0] += w * along;
                                    a[1] += w;
                                    a[2] += w * rgb[0];
                                    a[3] += w * rgb[1];
                                    a[4] += w * rgb[2];
                                }
                            }
                        }
                    }
                }
            }
        }
        for ((a, s), c) in acc.iter().zip(sdf).zip(colour) {
            if a[1] >= self.min_weight {
                let inv = 1.0 / a[1];
                *s = a[0] * inv;
                let near = if a[5] <= self.max_gap2 { NEAR } else { 0 };
                // +0.5 then truncation rounds (values are non-negative).
                *c = [
                    (a[2] * inv + 0.5).min(255.0) as u8,
                    (a[3] * inv + 0.5).min(255.0) as u8,
                    (a[4] * inv + 0.5).min(255.0) as u8,
                    OBSERVED | near,
                ];
            } else {
                *s = 0.0;
                *c = [0; 4];
            }
        }
    }
}
