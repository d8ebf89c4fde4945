//! Embedded deformation graph (Sumner et al. 2007, as ElasticFusion uses it
//! to close loops): a few hundred nodes sampled from the map in time order,
//! each with an affine correction (`R`, `t`) that is kept rigid by the cost.
//! A point observed at frame `τ` is moved by the `k` nodes nearest to it in
//! space among those nearest in time, so surfaces seen late in a loop bend
//! towards where they were seen first while old surfaces stay put.
//!
//! Use one graph per closure: [`DeformationGraph::from_samples`] (node
//! sampling), [`DeformationGraph::optimise`] (Gauss-Newton / Levenberg on
//! the sparse normal equations, rejected as a whole when the result is not
//! good enough), then [`DeformationGraph::apply_to_points`] and
//! [`DeformationGraph::apply_to_pose`] for the map and the trajectory.
//!
//! Frames and units: every position is in the world frame, in metres; poses
//! are `world_from_camera`; times are frame indices (`u32`).

mod apply;
mod optimise;

use glam::{DMat3, DVec3, Vec3};

use crate::random::SplitMix;

/// Most nodes a point may be influenced by (the fixed size of the per-point
/// neighbour arrays).
pub const MAX_INFLUENCE: usize = 8;

/// Settings of the graph and its optimisation.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DeformConfig {
    /// Nodes sampled from the map (evenly in time order); fewer when there
    /// are fewer finite samples.
    pub max_nodes: usize,
    /// Nodes that move a point (`k`; ElasticFusion uses 4), at most
    /// [`MAX_INFLUENCE`].
    pub influence: usize,
    /// Nodes each node is tied to by the smoothness term (besides its
    /// successor in time, which keeps the graph connected).
    pub neighbours: usize,
    /// Nodes nearest in time searched for the spatially nearest; the window
    /// grows past this to include nodes tied in time, up to `max_candidates`.
    pub time_window: usize,
    /// Cap on the candidate window (bounds the per-point cost when many nodes
    /// share one time, e.g. the first frame's surfels).
    pub max_candidates: usize,
    /// Weight of the rigidity term (`RᵀR = I`, unitless residuals).
    pub weight_rigidity: f64,
    /// Weight of the smoothness term (residuals in metres).
    pub weight_smoothness: f64,
    /// Weight of the rotation smoothness term (`Rⱼ - Rₖ` between
    /// neighbours, unitless): small, it only decides rotations the other
    /// terms leave free (nodes along a line), so they follow their
    /// neighbours instead of drifting.
    pub weight_rotation_smoothness: f64,
    /// Weight of the constraints and pins (residuals in metres), multiplied
    /// by each [`Constraint::weight`].
    pub weight_constraint: f64,
    /// Gauss-Newton iterations at most.
    pub max_iterations: usize,
    /// Accept only if every constraint (and pin) ends within this distance
    /// of its target (metres).
    pub max_constraint_error_m: f64,
    /// Accept only if every node's `|RᵀR - I|` (Frobenius) ends below this
    /// and its determinant is positive: nodes stay near rotations.
    pub max_orthogonality_error: f64,
    /// Constraints may lie this many frames outside the nodes' time range
    /// (a point fused after the graph was sampled); further is an error.
    pub time_tolerance: u32,
}

impl Default for DeformConfig {
    fn default() -> Self {
        Self {
            max_nodes: 400,
            influence: 4,
            neighbours: 4,
            time_window: 16,
            max_candidates: 128,
            // ElasticFusion's balance: constraints dominate, rigidity least.
            weight_rigidity: 1.0,
            weight_smoothness: 10.0,
            weight_rotation_smoothness: 1e-3,
            weight_constraint: 100.0,
            max_iterations: 10,
            max_constraint_error_m: 0.01,
            max_orthogonality_error: 0.1,
            time_tolerance: 30,
        }
    }
}

/// A point that must move: `source` (where it is now, world frame, metres,
/// observed at frame `time`) should end at `target`. A pin is a constraint
/// whose target is its source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Constraint {
    /// Position now (world frame, metres).
    pub source: Vec3,
    /// Position wanted after deformation (world frame, metres).
    pub target: Vec3,
    /// Frame index the source point belongs to (selects its nodes).
    pub time: u32,
    /// Relative weight (1 = normal); must be finite and `>= 0`.
    pub weight: f32,
}

impl Constraint {
    /// `source` (observed at frame `time`) should move to `target`; weight 1.
    #[must_use]
    pub fn new(source: Vec3, target: Vec3, time: u32) -> Self {
        Self {
            source,
            target,
            time,
            weight: 1.0,
        }
    }

    /// `point` (observed at frame `time`) must stay where it is; weight 1.
    #[must_use]
    pub fn pin(point: Vec3, time: u32) -> Self {
        Self::new(point, point, time)
    }
}

/// What an accepted optimisation did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeformReport {
    /// Gauss-Newton iterations taken (0 when the constraints already held).
    pub iterations: usize,
    /// Total weighted cost before (unitless sum of squared weighted residuals).
    pub initial_cost: f64,
    /// Total weighted cost after.
    pub final_cost: f64,
    /// Largest distance of a constraint's source from its target before (m).
    pub initial_max_error_m: f64,
    /// Largest distance of a deformed constraint source from its target (m).
    pub max_constraint_error_m: f64,
}

/// Why a graph could not be built or an optimisation was rejected. A
/// rejected optimisation leaves the graph unchanged.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum DeformError {
    /// `positions` and `times` (or `normals`) differ in length.
    #[error("length mismatch: {positions} positions, {other} times/normals")]
    LengthMismatch {
        /// Number of positions.
        positions: usize,
        /// Length of the other slice.
        other: usize,
    },
    /// Too few finite samples for a graph.
    #[error("too few graph nodes: {nodes} (need at least {needed})")]
    TooFewNodes {
        /// Nodes available.
        nodes: usize,
        /// Nodes needed (`influence + 1`).
        needed: usize,
    },
    /// Every sample has the same time: the graph could not bend along the
    /// trajectory.
    #[error("all samples have time {time}: the graph has no time span")]
    SingleTime {
        /// The one time.
        time: u32,
    },
    /// No constraints were given.
    #[error("no constraints")]
    NoConstraints,
    /// A constraint has a NaN or infinite coordinate or weight, or a
    /// negative weight.
    #[error("constraint {index} is not finite (or has a negative weight)")]
    NonFinite {
        /// Index into the constraint slice.
        index: usize,
    },
    /// A constraint's time is further outside the nodes' time range than the
    /// configured tolerance.
    #[error("constraint {index} has time {time}, outside the graph's {first}..={last}")]
    TimeOutOfRange {
        /// Index into the constraint slice.
        index: usize,
        /// Its time.
        time: u32,
        /// First node time.
        first: u32,
        /// Last node time.
        last: u32,
    },
    /// The normal equations could not be factored.
    #[error("singular normal equations")]
    Singular,
    /// The optimisation produced NaN or infinite values.
    #[error("the optimisation diverged (non-finite values)")]
    Diverged,
    /// The iterations ran out while the cost was still falling fast.
    #[error("not converged after {iterations} iterations (cost {cost})")]
    NotConverged {
        /// Iterations taken.
        iterations: usize,
        /// Cost at the end.
        cost: f64,
    },
    /// The optimisation did not lower the cost.
    #[error("cost not reduced ({initial} -> {final_cost})")]
    CostNotReduced {
        /// Cost before.
        initial: f64,
        /// Cost after.
        final_cost: f64,
    },
    /// A constraint (or pin) ended too far from its target.
    #[error("constraint error {max_error_m} m exceeds {limit_m} m")]
    ResidualTooLarge {
        /// Largest remaining error (m).
        max_error_m: f64,
        /// The configured limit (m).
        limit_m: f64,
    },
    /// A node's matrix ended far from a rotation (or a reflection).
    #[error("node {node} is not rigid (det {det}, orthogonality error {orthogonality})")]
    NotRigid {
        /// Node index.
        node: usize,
        /// Its determinant.
        det: f64,
        /// `|RᵀR - I|` (Frobenius).
        orthogonality: f64,
    },
}

/// One node: a sampled surfel position and its correction.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    /// Position `g` (world frame, metres).
    position: Vec3,
    /// Frame index of the sample.
    time: u32,
}

/// Per-node corrections, `p' = R (p - g) + g + t`. Kept apart from the nodes
/// so an optimisation works on a copy and commits only on success.
#[derive(Clone, Debug, PartialEq)]
struct Corrections {
    /// `R` per node (near a rotation).
    rotation: Vec<DMat3>,
    /// `t` per node (metres).
    translation: Vec<DVec3>,
}

impl Corrections {
    fn identity(n: usize) -> Self {
        Self {
            rotation: vec![DMat3::IDENTITY; n],
            translation: vec![DVec3::ZERO; n],
        }
    }
}

/// The nodes influencing one point and their normalised weights.
#[derive(Clone, Copy, Debug)]
struct Influence {
    nodes: [u32; MAX_INFLUENCE],
    weights: [f32; MAX_INFLUENCE],
    count: usize,
}

/// An embedded deformation graph over the world frame (metres), nodes in
/// time order (frame indices).
#[derive(Clone, Debug)]
pub struct DeformationGraph {
    config: DeformConfig,
    /// Sorted by `(time, sample index)`.
    nodes: Vec<Node>,
    /// Smoothness edges `(j, k)`: node `j`'s correction should carry `g_k`
    /// to `g_k + t_k`.
    edges: Vec<(u32, u32)>,
    corrections: Corrections,
}

impl DeformationGraph {
    /// Samples up to `config.max_nodes` nodes evenly from `positions` (world
    /// frame, metres) ordered by `times` (frame indices, e.g. each surfel's
    /// first or last update), and ties each node to its neighbours. Non-finite
    /// positions are skipped. All corrections start at the identity.
    ///
    /// # Errors
    /// [`DeformError::LengthMismatch`], [`DeformError::TooFewNodes`] (fewer
    /// than `influence + 1` finite samples), [`DeformError::SingleTime`].
    pub fn from_samples(
        positions: &[Vec3],
        times: &[u32],
        config: DeformConfig,
    ) -> Result<Self, DeformError> {
        if positions.len() != times.len() {
            return Err(DeformError::LengthMismatch {
                positions: positions.len(),
                other: times.len(),
            });
        }
        let config = DeformConfig {
            influence: config.influence.clamp(1, MAX_INFLUENCE),
            time_window: config.time_window.max(1),
            max_candidates: config.max_candidates.max(config.time_window.max(1)),
            ..config
        };
        let needed = config.influence + 1;
        let mut order: Vec<u32> = (0..positions.len() as u32)
            .filter(|&i| positions[i as usize].is_finite())
            .collect();
        if order.len() < needed || config.max_nodes < needed {
            return Err(DeformError::TooFewNodes {
                nodes: order.len().min(config.max_nodes),
                needed,
            });
        }
        order.sort_by_key(|&i| (times[i as usize], i));
        let first = times[order[0] as usize];
        if order.iter().all(|&i| times[i as usize] == first) {
            return Err(DeformError::SingleTime { time: first });
        }
        // Steps through the time-sorted samples: node density follows where
        // the map grew, as ElasticFusion's random sampling of the sorted map.
        // A fixed jitter inside each step keeps a regular map layout (rows of
        // a scan) from aliasing into nodes all on one line, which would leave
        // their rotation about that line unobserved.
        let count = order.len().min(config.max_nodes);
        let last = order.len() - 1;
        let nodes: Vec<Node> = (0..count)
            .map(|j| {
                // Both ends exact: the graph spans every sample's time.
                let at = if j == 0 || j + 1 == count {
                    j * last / (count - 1)
                } else {
                    let step = last as f64 / (count - 1) as f64;
                    ((j as f64 + jitter(j as u64)) * step) as usize
                };
                let i = order[at.min(last)] as usize;
                Node {
                    position: positions[i],
                    time: times[i],
                }
            })
            .collect();
        let mut graph = Self {
            corrections: Corrections::identity(nodes.len()),
            nodes,
            edges: Vec::new(),
            config,
        };
        graph.connect();
        Ok(graph)
    }

    /// Smoothness edges: each node to its successor in time (so the graph is
    /// one piece) and to its spatially nearest nodes among those nearest in
    /// time.
    fn connect(&mut self) {
        let n = self.nodes.len();
        let want = self.config.neighbours.min(MAX_INFLUENCE - 1);
        let mut edges = Vec::with_capacity(n * (want + 1));
        for j in 0..n {
            let node = self.nodes[j];
            if j + 1 < n {
                edges.push((j as u32, j as u32 + 1));
            }
            if want == 0 {
                continue;
            }
            // One more than wanted: the node finds itself at distance 0.
            let (found, count) = self.nearest(node.position, node.time, want + 2);
            for &(_, k) in found.iter().take(count) {
                if k as usize != j && k as usize != j + 1 {
                    edges.push((j as u32, k));
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        self.edges = edges;
    }

    /// Number of nodes.
    #[must_use]
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether the graph has no nodes (never true for a built graph).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// First and last node time (frame indices).
    #[must_use]
    pub fn time_range(&self) -> (u32, u32) {
        match (self.nodes.first(), self.nodes.last()) {
            (Some(a), Some(b)) => (a.time, b.time),
            _ => (0, 0),
        }
    }

    /// Node positions (world frame, metres), in time order.
    pub fn node_positions(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.nodes.iter().map(|n| n.position)
    }

    /// The settings the graph was built with (after clamping).
    #[must_use]
    pub fn config(&self) -> &DeformConfig {
        &self.config
    }

    /// Node index range of the candidates for time `t`: the
    /// `time_window` nodes nearest in time, widened to nodes tied in time
    /// with the farthest of them, at most `max_candidates`.
    fn candidates(&self, t: u32) -> (usize, usize) {
        let n = self.nodes.len();
        let time = |j: usize| i64::from(self.nodes[j].time);
        let t = i64::from(t);
        let start = self.nodes.partition_point(|node| i64::from(node.time) < t);
        let (mut lo, mut hi) = (start, start);
        let window = self.config.time_window.min(n);
        while hi - lo < window {
            let left = (lo > 0).then(|| t - time(lo - 1));
            let right = (hi < n).then(|| time(hi) - t);
            match (left, right) {
                (Some(l), Some(r)) if l < r => lo -= 1,
                (_, Some(_)) => hi += 1,
                (Some(_), None) => lo -= 1,
                (None, None) => break,
            }
        }
        let reach = (t - time(lo)).abs().max((time(hi - 1) - t).abs());
        let cap = self.config.max_candidates.min(n);
        while hi - lo < cap {
            if lo > 0 && (t - time(lo - 1)).abs() <= reach {
                lo -= 1;
            } else if hi < n && (time(hi) - t).abs() <= reach {
                hi += 1;
            } else {
                break;
            }
        }
        (lo, hi)
    }

    /// The `want` (<= MAX_INFLUENCE + 1) spatially nearest candidates of
    /// time `t`, nearest first, as `(squared distance, node)`.
    fn nearest(&self, p: Vec3, t: u32, want: usize) -> ([(f32, u32); MAX_INFLUENCE + 1], usize) {
        let want = want.min(MAX_INFLUENCE + 1);
        let mut best = [(f32::INFINITY, 0u32); MAX_INFLUENCE + 1];
        let mut count = 0;
        let (lo, hi) = self.candidates(t);
        for j in lo..hi {
            let d = (self.nodes[j].position - p).length_squared();
            if count < want {
                count += 1;
            } else if d >= best[count - 1].0 {
                continue;
            }
            // Insertion into the short sorted list.
            let mut at = count - 1;
            while at > 0 && best[at - 1].0 > d {
                best[at] = best[at - 1];
                at -= 1;
            }
            best[at] = (d, j as u32);
        }
        (best, count)
    }

    /// The `influence` nodes moving point `p` observed at frame `t`, weighted
    /// `(1 - d/d_max)²` (normalised) with `d_max` the distance of the next
    /// nearest candidate, as ElasticFusion.
    fn influence(&self, p: Vec3, t: u32) -> Influence {
        let k = self.config.influence;
        let (best, count) = self.nearest(p, t, k + 1);
        let mut out = Influence {
            nodes: [0; MAX_INFLUENCE],
            weights: [0.0; MAX_INFLUENCE],
            count: count.min(k),
        };
        if out.count == 0 {
            return out;
        }
        let d_max = if count > k {
            best[k].0.sqrt()
        } else {
            // Fewer candidates than k + 1: reach a little past the farthest.
            best[count - 1].0.sqrt() * 1.5
        };
        let mut sum = 0.0;
        for (i, &(d2, node)) in best.iter().take(out.count).enumerate() {
            out.nodes[i] = node;
            let w = if d_max > 0.0 && d_max.is_finite() {
                (1.0 - d2.sqrt() / d_max).max(0.0).powi(2)
            } else {
                0.0
            };
            out.weights[i] = w;
            sum += w;
        }
        if sum > 0.0 && sum.is_finite() {
            out.weights[..out.count].iter_mut().for_each(|w| *w /= sum);
        } else {
            // Equidistant candidates (or a point far from every node):
            // share the correction equally rather than drop it.
            let w = 1.0 / out.count as f32;
            out.weights[..out.count].iter_mut().for_each(|x| *x = w);
        }
        out
    }

    /// Solves for the corrections that carry every constraint's source to
    /// its target while keeping the graph rigid and smooth, and commits them
    /// only if the result is accepted: finite, cost reduced, every
    /// constraint within `max_constraint_error_m`, every node near a
    /// rotation. Otherwise the graph is unchanged and the error says why.
    /// Starts from the graph's current corrections (the identity for a new
    /// graph).
    ///
    /// # Errors
    /// [`DeformError::NoConstraints`], [`DeformError::NonFinite`],
    /// [`DeformError::TimeOutOfRange`] for bad input; [`DeformError::Singular`],
    /// [`DeformError::Diverged`], [`DeformError::NotConverged`],
    /// [`DeformError::CostNotReduced`], [`DeformError::ResidualTooLarge`],
    /// [`DeformError::NotRigid`] for a rejected result.
    pub fn optimise(&mut self, constraints: &[Constraint]) -> Result<DeformReport, DeformError> {
        if constraints.is_empty() {
            return Err(DeformError::NoConstraints);
        }
        let (first, last) = self.time_range();
        let tolerance = i64::from(self.config.time_tolerance);
        for (index, c) in constraints.iter().enumerate() {
            if !(c.source.is_finite() && c.target.is_finite() && c.weight.is_finite())
                || c.weight < 0.0
            {
                return Err(DeformError::NonFinite { index });
            }
            let t = i64::from(c.time);
            if t < i64::from(first) - tolerance || t > i64::from(last) + tolerance {
                return Err(DeformError::TimeOutOfRange {
                    index,
                    time: c.time,
                    first,
                    last,
                });
            }
        }
        let influences: Vec<Influence> = constraints
            .iter()
            .map(|c| self.influence(c.source, c.time))
            .collect();
        let (corrections, report) = optimise::solve(self, constraints, &influences)?;
        self.corrections = corrections;
        Ok(report)
    }

    /// Whether every correction is the identity (nothing would move).
    #[must_use]
    pub fn is_identity(&self) -> bool {
        self.corrections
            .rotation
            .iter()
            .all(|r| *r == DMat3::IDENTITY)
            && self
                .corrections
                .translation
                .iter()
                .all(|t| *t == DVec3::ZERO)
    }
}

/// A fixed pseudo-random number in `[0, 1)` for `j`: the first draw of
/// the stream seeded with `j`.
fn jitter(j: u64) -> f64 {
    SplitMix::new(j).next_f64()
}
