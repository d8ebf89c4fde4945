//! Levenberg-damped Gauss-Newton for the deformation graph on the sparse
//! normal equations (`faer`'s sparse Cholesky with its fill-reducing
//! ordering, simplicial: see [`NormalEquations::solve`]).
//!
//! Unknowns: 12 per node, the rows of `R` (`3a + b` for `R[a][b]`) then `t`
//! (`9 + a`). Only the rigidity rows are nonlinear; the smoothness and
//! constraint rows are linear in the unknowns, so few iterations suffice.

// Index loops mirror the matrix formulas (row a, column b).
#![allow(clippy::needless_range_loop)]

use super::{
    Constraint, Corrections, DeformError, DeformReport, DeformationGraph, Influence, MAX_INFLUENCE,
};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Par, Side};
use glam::{DMat3, DVec3};
use std::collections::HashMap;

const UNKNOWNS: usize = 12;
/// Entries one residual row has on one node at most (a rigidity row: two
/// columns of `R`, three rows each).
const ROW_ENTRIES: usize = 6;

/// A row's Jacobian entries on one node: the node, `(unknown, value)`
/// pairs, how many are used.
type NodeEntries = (u32, [(u8, f64); ROW_ENTRIES], usize);

/// One weighted residual row: its value and its Jacobian, grouped by node.
struct Row {
    residual: f64,
    weight: f64,
    nodes: [NodeEntries; MAX_INFLUENCE],
    count: usize,
}

impl Row {
    fn new(residual: f64, weight: f64) -> Self {
        Self {
            residual,
            weight,
            nodes: [(0, [(0, 0.0); ROW_ENTRIES], 0); MAX_INFLUENCE],
            count: 0,
        }
    }

    fn node(&mut self, node: u32, entries: &[(u8, f64)]) {
        if self.count == MAX_INFLUENCE {
            return;
        }
        let slot = &mut self.nodes[self.count];
        slot.0 = node;
        slot.2 = entries.len().min(ROW_ENTRIES);
        slot.1[..slot.2].copy_from_slice(&entries[..slot.2]);
        self.count += 1;
    }
}

/// The lower-triangular block-sparse normal equations `H δ = -g`.
struct Normal {
    /// Block index of node pair `(j, k)`, `j >= k`.
    pattern: HashMap<(u32, u32), usize>,
    /// Row-major 12x12 blocks (for `j == k` only the lower triangle is used).
    blocks: Vec<[f64; UNKNOWNS * UNKNOWNS]>,
    keys: Vec<(u32, u32)>,
    gradient: Vec<f64>,
    cost: f64,
}

impl Normal {
    fn new(nodes: usize) -> Self {
        Self {
            pattern: HashMap::new(),
            blocks: Vec::new(),
            keys: Vec::new(),
            gradient: vec![0.0; nodes * UNKNOWNS],
            cost: 0.0,
        }
    }

    fn clear(&mut self) {
        self.blocks.iter_mut().for_each(|b| b.fill(0.0));
        self.gradient.fill(0.0);
        self.cost = 0.0;
    }

    fn block(&mut self, j: u32, k: u32) -> usize {
        let key = (j.max(k), j.min(k));
        if let Some(&b) = self.pattern.get(&key) {
            return b;
        }
        self.blocks.push([0.0; UNKNOWNS * UNKNOWNS]);
        self.keys.push(key);
        let b = self.blocks.len() - 1;
        self.pattern.insert(key, b);
        b
    }

    fn add(&mut self, row: &Row) {
        let w = row.weight;
        self.cost += w * row.residual * row.residual;
        for x in 0..row.count {
            let (jx, ex, nx) = row.nodes[x];
            for &(ix, vx) in &ex[..nx] {
                self.gradient[jx as usize * UNKNOWNS + ix as usize] += w * vx * row.residual;
            }
            for y in 0..row.count {
                let (jy, ey, ny) = row.nodes[y];
                if jx < jy {
                    continue;
                }
                let b = self.block(jx, jy);
                let block = &mut self.blocks[b];
                for &(ix, vx) in &ex[..nx] {
                    for &(iy, vy) in &ey[..ny] {
                        if jx == jy && ix < iy {
                            continue;
                        }
                        block[ix as usize * UNKNOWNS + iy as usize] += w * vx * vy;
                    }
                }
            }
        }
    }

    /// Solves `(H + μ (diag H + floor)) δ = -g`.
    fn solve(&self, mu: f64) -> Result<Vec<f64>, DeformError> {
        let n = self.gradient.len();
        let mut max_diag: f64 = 0.0;
        for (key, block) in self.keys.iter().zip(&self.blocks) {
            if key.0 == key.1 {
                for i in 0..UNKNOWNS {
                    max_diag = max_diag.max(block[i * UNKNOWNS + i]);
                }
            }
        }
        if !max_diag.is_finite() || max_diag <= 0.0 {
            return Err(DeformError::Singular);
        }
        // The floor keeps directions no term reaches (a node whose edges are
        // collinear) at zero update instead of singular.
        let floor = 1e-9 * max_diag;
        let mut triplets = Vec::with_capacity(self.blocks.len() * UNKNOWNS * UNKNOWNS);
        for (&(j, k), block) in self.keys.iter().zip(&self.blocks) {
            let (r0, c0) = (j as usize * UNKNOWNS, k as usize * UNKNOWNS);
            for a in 0..UNKNOWNS {
                for b in 0..UNKNOWNS {
                    if j == k && b > a {
                        continue;
                    }
                    let mut v = block[a * UNKNOWNS + b];
                    if j == k && a == b {
                        v += mu * (v + floor) + floor;
                    }
                    if v != 0.0 {
                        triplets.push(Triplet::new(r0 + a, c0 + b, v));
                    }
                }
            }
        }
        let h = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets)
            .map_err(|_| DeformError::Singular)?;
        // Simplicial, one thread: plain scalar loops, the same bits on every
        // target. `sp_cholesky` picks the supernodal factorisation for this
        // graph, whose dense kernels `faer` chooses at run time (AVX2 and
        // FMA on x86-64, simd128 on wasm): native and wasm then differ in
        // the last bits from the first closure on (`docs/performance.md#determinism`).
        let symbolic = factorize_symbolic_cholesky(
            h.symbolic(),
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
                ..Default::default()
            },
        )
        .map_err(|_| DeformError::Singular)?;
        let mut values = vec![0.0; symbolic.len_val()];
        let mut buffer = MemBuffer::try_new(
            symbolic
                .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
                .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)),
        )
        .map_err(|_| DeformError::Singular)?;
        let stack = MemStack::new(&mut buffer);
        let llt = symbolic
            .factorize_numeric_llt(
                &mut values,
                h.as_ref(),
                Side::Lower,
                Default::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
            .map_err(|_| DeformError::Singular)?;
        let mut x = faer::Col::<f64>::from_fn(n, |i| -self.gradient[i]);
        llt.solve_in_place_with_conj(Conj::No, x.as_mat_mut(), Par::Seq, stack);
        let step: Vec<f64> = (0..n).map(|i| x[i]).collect();
        if step.iter().all(|v| v.is_finite()) {
            Ok(step)
        } else {
            Err(DeformError::Singular)
        }
    }
}

/// Rows of every term at `c`, accumulated into `normal` (and its cost).
fn assemble(
    graph: &DeformationGraph,
    constraints: &[Constraint],
    influences: &[Influence],
    c: &Corrections,
    normal: &mut Normal,
) {
    normal.clear();
    let config = &graph.config;
    // Rigidity: the columns of R orthonormal.
    for (j, r) in c.rotation.iter().enumerate() {
        let j = j as u32;
        for p in 0..3 {
            for q in p..3 {
                let cp = r.col(p);
                let cq = r.col(q);
                let mut entries = [(0u8, 0.0); ROW_ENTRIES];
                let (residual, len) = if p == q {
                    for a in 0..3 {
                        entries[a] = ((3 * a + p) as u8, 2.0 * cp[a]);
                    }
                    (cp.dot(cp) - 1.0, 3)
                } else {
                    for a in 0..3 {
                        entries[a] = ((3 * a + p) as u8, cq[a]);
                        entries[3 + a] = ((3 * a + q) as u8, cp[a]);
                    }
                    (cp.dot(cq), 6)
                };
                let mut row = Row::new(residual, config.weight_rigidity);
                row.node(j, &entries[..len]);
                normal.add(&row);
            }
        }
    }
    // Smoothness: node j's correction carries g_k where node k's does.
    for &(j, k) in &graph.edges {
        let (ju, ku) = (j as usize, k as usize);
        let gj = graph.nodes[ju].position.as_dvec3();
        let gk = graph.nodes[ku].position.as_dvec3();
        let d = gk - gj;
        let moved = c.rotation[ju] * d + gj + c.translation[ju] - (gk + c.translation[ku]);
        for a in 0..3 {
            let mut row = Row::new(moved[a], config.weight_smoothness);
            let mut ej = [(0u8, 0.0); 4];
            for b in 0..3 {
                ej[b] = ((3 * a + b) as u8, d[b]);
            }
            ej[3] = ((9 + a) as u8, 1.0);
            row.node(j, &ej);
            row.node(k, &[((9 + a) as u8, -1.0)]);
            normal.add(&row);
        }
        if config.weight_rotation_smoothness > 0.0 {
            let diff = c.rotation[ju] - c.rotation[ku];
            for a in 0..3 {
                for b in 0..3 {
                    let i = (3 * a + b) as u8;
                    let mut row = Row::new(diff.col(b)[a], config.weight_rotation_smoothness);
                    row.node(j, &[(i, 1.0)]);
                    row.node(k, &[(i, -1.0)]);
                    normal.add(&row);
                }
            }
        }
    }
    // Constraints: the deformed source at its target.
    for (con, inf) in constraints.iter().zip(influences) {
        let s = con.source.as_dvec3();
        let moved = deformed(graph, c, s, inf);
        let residual = moved - con.target.as_dvec3();
        let w = config.weight_constraint * f64::from(con.weight);
        for a in 0..3 {
            let mut row = Row::new(residual[a], w);
            for i in 0..inf.count {
                let j = inf.nodes[i];
                let alpha = f64::from(inf.weights[i]);
                let v = s - graph.nodes[j as usize].position.as_dvec3();
                let mut e = [(0u8, 0.0); 4];
                for b in 0..3 {
                    e[b] = ((3 * a + b) as u8, alpha * v[b]);
                }
                e[3] = ((9 + a) as u8, alpha);
                row.node(j, &e);
            }
            normal.add(&row);
        }
    }
}

/// `s + Σ αᵢ ((Rᵢ - I)(s - gᵢ) + tᵢ)`.
fn deformed(graph: &DeformationGraph, c: &Corrections, s: DVec3, inf: &Influence) -> DVec3 {
    let mut d = DVec3::ZERO;
    for i in 0..inf.count {
        let j = inf.nodes[i] as usize;
        let g = graph.nodes[j].position.as_dvec3();
        d += f64::from(inf.weights[i])
            * ((c.rotation[j] - DMat3::IDENTITY) * (s - g) + c.translation[j]);
    }
    s + d
}

fn max_error(
    graph: &DeformationGraph,
    constraints: &[Constraint],
    influences: &[Influence],
    c: &Corrections,
) -> f64 {
    constraints
        .iter()
        .zip(influences)
        .map(|(con, inf)| {
            (deformed(graph, c, con.source.as_dvec3(), inf) - con.target.as_dvec3()).length()
        })
        .fold(0.0, f64::max)
}

fn stepped(c: &Corrections, step: &[f64]) -> Corrections {
    let mut out = c.clone();
    for (j, (r, t)) in out
        .rotation
        .iter_mut()
        .zip(out.translation.iter_mut())
        .enumerate()
    {
        let x = &step[j * UNKNOWNS..(j + 1) * UNKNOWNS];
        let mut cols = [r.x_axis, r.y_axis, r.z_axis];
        for a in 0..3 {
            for b in 0..3 {
                cols[b][a] += x[3 * a + b];
            }
        }
        *r = DMat3::from_cols(cols[0], cols[1], cols[2]);
        *t += DVec3::new(x[9], x[10], x[11]);
    }
    out
}

fn check_rigid(c: &Corrections, limit: f64) -> Result<(), DeformError> {
    for (node, r) in c.rotation.iter().enumerate() {
        let e = r.transpose() * *r - DMat3::IDENTITY;
        let orthogonality = (0..3)
            .map(|b| e.col(b).length_squared())
            .sum::<f64>()
            .sqrt();
        let det = r.determinant();
        if !(det > 0.0 && orthogonality <= limit) {
            return Err(DeformError::NotRigid {
                node,
                det,
                orthogonality,
            });
        }
    }
    Ok(())
}

/// Relative cost decrease below which the iterations stop.
const CONVERGED: f64 = 1e-8;
/// Relative decrease of the last step above which running out of
/// iterations means "not converged" rather than "converged to this".
const STILL_FALLING: f64 = 1e-2;

/// Optimises a copy of the graph's corrections; returns it with the report
/// when accepted (see [`DeformationGraph::optimise`]).
pub(super) fn solve(
    graph: &DeformationGraph,
    constraints: &[Constraint],
    influences: &[Influence],
) -> Result<(Corrections, DeformReport), DeformError> {
    let config = &graph.config;
    let mut current = graph.corrections.clone();
    let mut normal = Normal::new(graph.nodes.len());
    assemble(graph, constraints, influences, &current, &mut normal);
    let initial_cost = normal.cost;
    let initial_max_error_m = max_error(graph, constraints, influences, &current);
    if !initial_cost.is_finite() {
        return Err(DeformError::Diverged);
    }
    let mut report = DeformReport {
        iterations: 0,
        initial_cost,
        final_cost: initial_cost,
        initial_max_error_m,
        max_constraint_error_m: initial_max_error_m,
    };
    if initial_cost <= f64::MIN_POSITIVE {
        // Nothing to correct: constraints hold and the nodes are rotations.
        return Ok((current, report));
    }
    let mut cost = initial_cost;
    let mut mu = 1e-4;
    let mut last_decrease = 1.0;
    let mut scratch = Normal::new(graph.nodes.len());
    while report.iterations < config.max_iterations {
        report.iterations += 1;
        let step = normal.solve(mu)?;
        let candidate = stepped(&current, &step);
        assemble(graph, constraints, influences, &candidate, &mut scratch);
        let new_cost = scratch.cost;
        if !new_cost.is_finite() {
            return Err(DeformError::Diverged);
        }
        if new_cost < cost {
            last_decrease = (cost - new_cost) / cost;
            current = candidate;
            cost = new_cost;
            std::mem::swap(&mut normal, &mut scratch);
            mu = (mu * 0.1).max(1e-8);
            if last_decrease < CONVERGED || cost <= f64::MIN_POSITIVE {
                break;
            }
        } else {
            mu *= 10.0;
            if mu > 1e8 {
                // No damping finds a lower cost: a minimum (or stuck); the
                // acceptance checks below decide.
                last_decrease = 0.0;
                break;
            }
        }
    }
    report.final_cost = cost;
    report.max_constraint_error_m = max_error(graph, constraints, influences, &current);
    let finite = current.rotation.iter().all(|r| r.is_finite())
        && current.translation.iter().all(|t| t.is_finite())
        && report.max_constraint_error_m.is_finite();
    if !finite {
        return Err(DeformError::Diverged);
    }
    if cost >= initial_cost {
        return Err(DeformError::CostNotReduced {
            initial: initial_cost,
            final_cost: cost,
        });
    }
    if report.max_constraint_error_m > config.max_constraint_error_m {
        if report.iterations >= config.max_iterations && last_decrease > STILL_FALLING {
            return Err(DeformError::NotConverged {
                iterations: report.iterations,
                cost,
            });
        }
        return Err(DeformError::ResidualTooLarge {
            max_error_m: report.max_constraint_error_m,
            limit_m: config.max_constraint_error_m,
        });
    }
    check_rigid(&current, config.max_orthogonality_error)?;
    Ok((current, report))
}
