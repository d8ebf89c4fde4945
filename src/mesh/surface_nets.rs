//! Surface nets on the sparse grid: one vertex per cell the zero level
//! crosses (the mean of the crossings on its edges), one quad per crossed
//! voxel edge joining the four cells around it. Cells with an unobserved
//! corner make no vertex, and a quad needs all four vertices, so the mesh
//! stops where the observations stop.

use glam::{IVec3, Vec3};
use rayon::prelude::*;

use super::grid::{local_index, neighbour_slot, Grid, B, BV, NEAR, NONE, OBSERVED};
use super::TriangleMesh;

/// The 8 corners of a cell, as offsets from its lowest voxel; corner `i`
/// has offset `(i & 1, (i >> 1) & 1, (i >> 2) & 1)`.
const CORNERS: [IVec3; 8] = [
    IVec3::new(0, 0, 0),
    IVec3::new(1, 0, 0),
    IVec3::new(0, 1, 0),
    IVec3::new(1, 1, 0),
    IVec3::new(0, 0, 1),
    IVec3::new(1, 0, 1),
    IVec3::new(0, 1, 1),
    IVec3::new(1, 1, 1),
];

/// The 12 cell edges as pairs of corners.
const EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Progress calls per parallel stage.
const BATCHES: usize = 8;

/// Read access to the voxels around one block.
#[derive(Clone, Copy)]
struct Around<'a> {
    grid: &'a Grid,
    table: &'a [u32; 27],
}

impl Around<'_> {
    /// Flat index of voxel `v` (block-local; each component -8..16), or
    /// `None` when its block does not exist.
    #[inline(always)]
    fn voxel(&self, v: IVec3) -> Option<usize> {
        let block = self.table[neighbour_slot(v >> 3)];
        (block != NONE).then(|| block as usize * BV + local_index(v & 7))
    }

    /// Signed distance at voxel `v`, `None` if unobserved.
    #[inline(always)]
    fn sdf(&self, v: IVec3) -> Option<f32> {
        let i = self.voxel(v)?;
        (self.grid.colour[i][3] & OBSERVED != 0).then(|| self.grid.sdf[i])
    }

    /// Whether some corner of the cell whose lowest voxel is `c` lies within
    /// `MeshConfig::max_gap_voxels` of a surfel centre: a crossing far from every surfel
    /// is the kernel's guess, not a measurement.
    #[inline(always)]
    fn near_surfel(&self, c: IVec3) -> bool {
        CORNERS.iter().any(|d| {
            self.voxel(c + *d)
                .is_some_and(|i| self.grid.colour[i][3] & NEAR != 0)
        })
    }

    /// The distances at the 8 corners of the cell whose lowest voxel is
    /// `c`, if all are observed and the zero level crosses the cell.
    #[inline(always)]
    fn crossed_cell(&self, c: IVec3) -> Option<[f32; 8]> {
        let mut s = [0.0f32; 8];
        let mut negative = 0u32;
        for (k, d) in CORNERS.iter().enumerate() {
            s[k] = self.sdf(c + *d)?;
            negative += u32::from(s[k] < 0.0);
        }
        (negative != 0 && negative != 8).then_some(s)
    }
}

/// Extracts the mesh of `grid` into `mesh` (cleared by the caller).
///
/// Phases, in order: `number_vertex_cells_into`, `write_vertices_into`,
/// `quads_into`, `drop_unused_vertices`.
pub(super) fn extract(grid: &mut Grid, mesh: &mut TriangleMesh, progress: &mut dyn FnMut(f32)) {
    let blocks = grid.keys.len();
    let mut cell_vertex = std::mem::take(&mut grid.cell_vertex);
    cell_vertex.clear();
    cell_vertex.resize(blocks * BV, NONE);
    if blocks == 0 {
        grid.cell_vertex = cell_vertex;
        return;
    }
    let batch = blocks.div_ceil(BATCHES).max(1);
    let mut counts = vec![0u32; blocks];
    number_vertex_cells_into(grid, batch, &mut cell_vertex, &mut counts, progress);
    write_vertices_into(grid, &counts, &mut cell_vertex, mesh);
    progress(0.6);
    grid.cell_vertex = cell_vertex;
    quads_into(grid, batch, &mut mesh.triangles, progress);
    drop_unused_vertices(mesh, &mut grid.remap);
}

/// Which cells have a vertex: per block, each such cell's index among the
/// block's vertex cells into `cell_vertex` (`NONE` for the others) and their
/// number into `counts`. Reports progress from 0 to 0.3.
fn number_vertex_cells_into(
    g: &Grid,
    batch: usize,
    cell_vertex: &mut [u32],
    counts: &mut [u32],
    progress: &mut dyn FnMut(f32),
) {
    let blocks = counts.len();
    for (n_done, (chunk, counts)) in cell_vertex
        .chunks_mut(batch * BV)
        .zip(counts.chunks_mut(batch))
        .enumerate()
    {
        let first = n_done * batch;
        chunk
            .par_chunks_mut(BV)
            .zip(counts.par_iter_mut())
            .enumerate()
            .for_each(|(j, (cells, count))| {
                let around = Around {
                    grid: g,
                    table: &g.neighbours[first + j],
                };
                let mut n = 0;
                for (i, cell) in cells.iter_mut().enumerate() {
                    let c = IVec3::new(i as i32 % B, (i as i32 / B) % B, i as i32 / (B * B));
                    if around.crossed_cell(c).is_some() && around.near_surfel(c) {
                        *cell = n;
                        n += 1;
                    }
                }
                *count = n;
            });
        progress(0.3 * ((n_done + 1) * batch).min(blocks) as f32 / blocks as f32);
    }
}

/// Writes the vertices into `mesh` (world frame, metres), each block's
/// share from where it starts (after the blocks before it, `counts` per
/// block); the block-local indices in `cell_vertex` become mesh indices.
fn write_vertices_into(g: &Grid, counts: &[u32], cell_vertex: &mut [u32], mesh: &mut TriangleMesh) {
    let total: usize = counts.iter().map(|&c| c as usize).sum();
    mesh.positions.resize(total, Vec3::ZERO);
    mesh.normals.resize(total, Vec3::ZERO);
    mesh.colours.resize(total, [0, 0, 0, 255]);
    let mut parts = Vec::with_capacity(counts.len());
    let (mut p, mut n, mut c) = (
        mesh.positions.as_mut_slice(),
        mesh.normals.as_mut_slice(),
        mesh.colours.as_mut_slice(),
    );
    let mut offset = 0u32;
    for (b, cells) in cell_vertex.chunks_mut(BV).enumerate() {
        let k = counts[b] as usize;
        let (p0, p1) = p.split_at_mut(k);
        let (n0, n1) = n.split_at_mut(k);
        let (c0, c1) = c.split_at_mut(k);
        parts.push((b, offset, cells, p0, n0, c0));
        (p, n, c) = (p1, n1, c1);
        offset += counts[b];
    }
    parts
        .into_par_iter()
        .for_each(|(b, offset, cells, positions, normals, colours)| {
            let around = Around {
                grid: g,
                table: &g.neighbours[b],
            };
            let origin = g.keys[b] * B;
            for (i, cell) in cells.iter_mut().enumerate() {
                if *cell == NONE {
                    continue;
                }
                let c = IVec3::new(i as i32 % B, (i as i32 / B) % B, i as i32 / (B * B));
                let Some(s) = around.crossed_cell(c) else {
                    continue;
                };
                let j = *cell as usize;
                let (local, normal, colour) = vertex(&around, c, &s);
                positions[j] = ((origin + c).as_vec3() + local) * g.voxel;
                normals[j] = normal;
                colours[j] = colour;
                *cell += offset;
            }
        });
}

/// Appends to `triangles` a quad (two triangles) for every crossed voxel
/// edge, block by block in block order (each block the edges whose lower
/// voxel lies in it; `g.cell_vertex` holds mesh indices). Reports progress
/// from 0.6 to 1.
fn quads_into(
    g: &Grid,
    batch: usize,
    triangles: &mut Vec<[u32; 3]>,
    progress: &mut dyn FnMut(f32),
) {
    let blocks = g.keys.len();
    for start in (0..blocks).step_by(batch) {
        let end = (start + batch).min(blocks);
        let part = (start..end)
            .into_par_iter()
            .fold(Vec::new, |mut out, b| {
                block_quads_into(g, b, &mut out);
                out
            })
            .reduce(Vec::new, |mut a, mut b| {
                a.append(&mut b);
                a
            });
        triangles.extend_from_slice(&part);
        progress(0.6 + 0.4 * end as f32 / blocks as f32);
    }
}

/// Removes the vertices no triangle uses (cells whose neighbours around
/// every crossed edge were not all there), keeping the order of the rest.
fn drop_unused_vertices(mesh: &mut TriangleMesh, remap: &mut Vec<u32>) {
    remap.clear();
    remap.resize(mesh.positions.len(), NONE);
    for &i in mesh.triangles.iter().flatten() {
        remap[i as usize] = 0;
    }
    let mut kept = 0usize;
    for (old, slot) in remap.iter_mut().enumerate() {
        if *slot != NONE {
            *slot = kept as u32;
            mesh.positions[kept] = mesh.positions[old];
            mesh.normals[kept] = mesh.normals[old];
            mesh.colours[kept] = mesh.colours[old];
            kept += 1;
        }
    }
    mesh.positions.truncate(kept);
    mesh.normals.truncate(kept);
    mesh.colours.truncate(kept);
    for i in mesh.triangles.iter_mut().flatten() {
        *i = remap[*i as usize];
    }
}

/// Position (cell-local, 0..1 per axis), unit normal (along the distance
/// gradient) and colour (trilinear) of the vertex of cell `c` with corner
/// distances `s`.
fn vertex(around: &Around, c: IVec3, s: &[f32; 8]) -> (Vec3, Vec3, [u8; 4]) {
    let mut sum = Vec3::ZERO;
    let mut crossings = 0.0f32;
    for &(a, b) in &EDGES {
        if (s[a] < 0.0) != (s[b] < 0.0) {
            let t = s[a] / (s[a] - s[b]);
            sum += CORNERS[a].as_vec3().lerp(CORNERS[b].as_vec3(), t);
            crossings += 1.0;
        }
    }
    let local = (sum / crossings.max(1.0)).clamp(Vec3::ZERO, Vec3::ONE);
    let gradient = Vec3::new(
        (s[1] + s[3] + s[5] + s[7]) - (s[0] + s[2] + s[4] + s[6]),
        (s[2] + s[3] + s[6] + s[7]) - (s[0] + s[1] + s[4] + s[5]),
        (s[4] + s[5] + s[6] + s[7]) - (s[0] + s[1] + s[2] + s[3]),
    );
    let normal = gradient.try_normalize().unwrap_or(Vec3::NEG_Y);
    let mut rgb = [0.0f32; 3];
    for d in &CORNERS {
        let w = [0, 1, 2]
            .iter()
            .map(|&a| if d[a] == 1 { local[a] } else { 1.0 - local[a] })
            .product::<f32>();
        if let Some(i) = around.voxel(c + *d) {
            let col = around.grid.colour[i];
            for (acc, &v) in rgb.iter_mut().zip(&col[..3]) {
                *acc += w * f32::from(v);
            }
        }
    }
    let colour = [
        (rgb[0] + 0.5).min(255.0) as u8,
        (rgb[1] + 0.5).min(255.0) as u8,
        (rgb[2] + 0.5).min(255.0) as u8,
        255,
    ];
    (local, normal, colour)
}

/// Appends the triangles of block `b`'s crossed edges to `out`.
fn block_quads_into(g: &Grid, b: usize, out: &mut Vec<[u32; 3]>) {
    let around = Around {
        grid: g,
        table: &g.neighbours[b],
    };
    let cell = |v: IVec3| around.voxel(v).map_or(NONE, |i| g.cell_vertex[i]);
    for i in 0..BV as i32 {
        let v = IVec3::new(i % B, (i / B) % B, i / (B * B));
        let Some(s0) = around.sdf(v) else {
            continue;
        };
        for axis in 0..3 {
            let (ea, eb, ec) = (
                IVec3::AXES[axis],
                IVec3::AXES[(axis + 1) % 3],
                IVec3::AXES[(axis + 2) % 3],
            );
            let Some(s1) = around.sdf(v + ea) else {
                continue;
            };
            if (s0 < 0.0) == (s1 < 0.0) {
                continue;
            }
            // The four cells around the edge, counter-clockwise about +axis.
            let q = [cell(v), cell(v - eb), cell(v - eb - ec), cell(v - ec)];
            if q.contains(&NONE) {
                continue;
            }
            if s0 < 0.0 {
                // Outside (positive) towards +axis: the quad faces +axis.
                out.push([q[0], q[1], q[2]]);
                out.push([q[0], q[2], q[3]]);
            } else {
                out.push([q[0], q[2], q[1]]);
                out.push([q[0], q[3], q[2]]);
            }
        }
    }
}
