//! A general Gauss-Helmert adjustment (docs/model.md section 2) for conditions that each involve
//! their own `K` uncorrelated observations: `f_i(p; l_i) = 0`, `l_i = (l_i1, .., l_iK)`
//! (K = 2 for a calibration reading, (Dz, Ng); K = 3 for a triad position's three means).
//!
//! Each iteration linearises at the current parameters and the current *adjusted*
//! observations, `A dp + B v + w = 0` with `w = f(p0; l + v0) - B v0`, and solves the
//! weighted least-squares problem `min || Q_ww^-1/2 (A dp + w) ||` by a QR of the
//! column-equilibrated design with the right-hand side as its last column: no normal matrix
//! is inverted and no N x N matrix is formed (`Q_ww` is diagonal). The QR is taken by blocks
//! of [`QR_BLOCK`] rows (a tall-skinny QR: each block's Householder QR, faer's, taken with the
//! triangle of the blocks before it), so the weighted design is formed a block at a time
//! from `A` and never held whole. Time O(N m^2), memory O(N (m + 3 K)): `A`, the
//! residuals, `B` and each condition's misclosure and variance; the observations themselves
//! are the caller's ([`Observations`]). The per-condition passes (linearising, residuals,
//! redundancy) run on the rayon pool in fixed tasks of [`TASK_ROWS`] rows, their sums taken
//! in row order within a task and the tasks' added in their order (the same bits on any
//! number of cores; a problem of one task has those of a single pass); the QR on the
//! calling thread and, for a large problem, one of its own ([`Linearised::triangle`] says
//! why).

use faer::prelude::*;
use rayon::prelude::{IndexedParallelIterator, ParallelIterator, ParallelSlice, ParallelSliceMut};

/// Rows of the weighted design taken into the QR at a time.
pub const QR_BLOCK: usize = 1024;

/// Rows from which the QR is taken in two halves at once, each on a thread of its own
/// ([`Linearised::triangle`]).
const SPLIT_ROWS: usize = 16 * QR_BLOCK;

/// Rows a parallel task takes (linearising, residuals, redundancy): fixed, so that what is
/// summed is summed in the same order on any number of cores.
pub(crate) const TASK_ROWS: usize = 16_384;

/// The observations of a problem: each condition's `K` values and their sds, held as slices
/// ([`Held`]) or formed from the caller's own records on each call, so that a large problem
/// keeps no copy of them.
pub trait Observations<const K: usize>: Sync {
    /// Number of conditions.
    fn count(&self) -> usize;
    /// Condition `i`'s observations and their sds.
    fn get(&self, i: usize) -> ([f64; K], [f64; K]);
}

/// Observations and their sds held as slices, a row a condition.
#[derive(Clone, Copy, Debug)]
pub struct Held<'a, const K: usize> {
    l: &'a [[f64; K]],
    sigma: &'a [[f64; K]],
}

impl<'a, const K: usize> Held<'a, K> {
    /// `l` with sds `sigma`, of one length.
    pub fn new(l: &'a [[f64; K]], sigma: &'a [[f64; K]]) -> Self {
        assert_eq!(
            sigma.len(),
            l.len(),
            "one set of sigmas per condition's observations"
        );
        Held { l, sigma }
    }
}

impl<const K: usize> Observations<K> for Held<'_, K> {
    fn count(&self) -> usize {
        self.l.len()
    }
    #[inline]
    fn get(&self, i: usize) -> ([f64; K], [f64; K]) {
        (self.l[i], self.sigma[i])
    }
}

/// The conditions of a problem, each on `K` observations of its own.
pub trait Conditions<const K: usize = 2>: Sync {
    /// Number of parameters.
    fn n_params(&self) -> usize;
    /// Condition `i` at parameters `p` and observations `l`: returns `f` and
    /// `B = (df/dl_1, .., df/dl_K)`, and writes `A = df/dp` into `a`.
    fn eval(&self, i: usize, p: &[f64], l: [f64; K], a: &mut [f64]) -> (f64, [f64; K]);
}

/// Iteration settings.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Most iterations before giving up.
    pub max_iterations: usize,
    /// Converged when every parameter change is below `tolerance` times its sd and every
    /// residual change below `tolerance` times its observation's sd, or either is at the
    /// level of rounding (`1e-13` of the value it changes).
    pub tolerance: f64,
    /// A column whose part independent of the columns before it is below this fraction of its
    /// norm is not estimable.
    pub rank_tolerance: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_iterations: 50,
            tolerance: 1e-9,
            rank_tolerance: 1e-11,
        }
    }
}

/// Why an adjustment has no answer.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GhError {
    /// Fewer conditions than parameters.
    #[error("{n} observations for {m} parameters")]
    TooFewObservations {
        /// Conditions.
        n: usize,
        /// Parameters.
        m: usize,
    },
    /// The design cannot determine parameter `index` (it depends on the parameters before it).
    #[error("parameter {index} is not estimable")]
    NotEstimable {
        /// Index of the parameter.
        index: usize,
    },
    /// A condition has zero variance (both its observations' sd and derivatives vanish).
    #[error("condition {index} has zero variance")]
    ZeroVariance {
        /// Index of the condition.
        index: usize,
    },
    /// The iteration did not settle.
    #[error("no convergence after {iterations} iterations")]
    NotConverged {
        /// Iterations run.
        iterations: usize,
    },
    /// A value became infinite or NaN.
    #[error("a non-finite value appeared in iteration {iteration}")]
    NonFinite {
        /// Iteration.
        iteration: usize,
    },
}

/// The adjusted solution.
#[derive(Clone, Debug)]
pub struct Solution<const K: usize = 2> {
    /// Parameters.
    pub p: Vec<f64>,
    /// Cofactor matrix of the parameters (a-priori covariance, sigma0 = 1), row-major m x m.
    pub q_pp: Vec<f64>,
    /// Residuals of the observations of each condition.
    pub v: Vec<[f64; K]>,
    /// Condition residual `B v` (the misclosure taken up), in the condition's unit.
    pub misclosure: Vec<f64>,
    /// Variance of each condition, `B Q_ll B^T`.
    pub q_ww: Vec<f64>,
    /// The observations' shares of `q_ww`: `(B_ik sigma_ik)^2`.
    pub q_parts: Vec<[f64; K]>,
    /// Redundancy number of each condition, `1 - h_i`.
    pub redundancy: Vec<f64>,
    /// Normalised residual (Baarda's w, a-priori sigma0 = 1); 0 where the redundancy is 0.
    pub w_test: Vec<f64>,
    /// `v^T P v`.
    pub vtpv: f64,
    /// Degrees of freedom, N - m.
    pub dof: usize,
    /// Iterations run.
    pub iterations: usize,
    /// The design `A = df/dp` at the solution, row-major n x m.
    pub a: Vec<f64>,
    /// `B = df/dl` at the solution, per condition.
    pub b: Vec<[f64; K]>,
}

impl<const K: usize> Solution<K> {
    /// A-posteriori variance factor: `v^T P v / r` (1 when r = 0).
    pub fn sigma0(&self) -> f64 {
        if self.dof == 0 {
            1.0
        } else {
            (self.vtpv / self.dof as f64).sqrt()
        }
    }

    /// A-priori sd of parameter `j`.
    pub fn sigma_apriori(&self, j: usize) -> f64 {
        let m = self.p.len();
        self.q_pp[j * m + j].max(0.0).sqrt()
    }
}

/// Changes below this many sds that no longer contract are rounding, not iteration.
const ROUNDING_FLOOR: f64 = 1e-6;

/// Inverse of an upper-triangular m x m matrix (row-major): faer's triangular solve of
/// R X = I.
fn invert_upper(r: &[f64], m: usize) -> Vec<f64> {
    let upper = Mat::<f64>::from_fn(m, m, |i, j| if j >= i { r[i * m + j] } else { 0.0 });
    let mut inv = Mat::<f64>::identity(m, m);
    upper.as_ref().solve_upper_triangular_in_place(inv.as_mut());
    (0..m * m).map(|k| inv[(k / m, k % m)]).collect()
}

/// A workspace for the thin QRs of stacked blocks of `cols` columns (at most `rows` rows):
/// faer's Householder QR in place, sequential, in buffers kept from one block to the next.
/// (`Mat::qr` copies each block, allocates its Householder factors and scratch, and splits
/// out Q and R.)
struct Householder {
    x: Mat<f64>,
    q_coeff: Mat<f64>,
    scratch: faer::dyn_stack::MemBuffer,
}

impl Householder {
    fn new(rows: usize, cols: usize) -> Self {
        use faer::linalg::qr::no_pivoting::factor;
        let block = factor::recommended_block_size::<f64>(rows, cols);
        let req = factor::qr_in_place_scratch::<f64>(rows, cols, block, Par::Seq, default_spec());
        Householder {
            x: Mat::zeros(rows, cols),
            q_coeff: Mat::zeros(cols, cols),
            scratch: faer::dyn_stack::MemBuffer::new(req),
        }
    }

    /// The upper triangle (row-major `cols` x `cols`) of the thin QR of the first `rows`
    /// rows, once [`Householder::fill`] has set them.
    fn upper(&mut self, rows: usize) -> Vec<f64> {
        use faer::linalg::qr::no_pivoting::factor;
        let cols = self.x.ncols();
        let size = rows.min(cols);
        let block = factor::recommended_block_size::<f64>(rows, cols);
        let x = self.x.as_mut().subrows_mut(0, rows);
        let q = self
            .q_coeff
            .as_mut()
            .subrows_mut(0, block)
            .subcols_mut(0, size);
        factor::qr_in_place(
            x,
            q,
            Par::Seq,
            faer::dyn_stack::MemStack::new(&mut self.scratch),
            default_spec(),
        );
        let mut r = vec![0.0; cols * cols];
        for i in 0..size {
            for j in i..cols {
                r[i * cols + j] = self.x[(i, j)];
            }
        }
        r
    }

    /// Sets the first `rows` rows of each column `j` by `column(j, slice)`.
    #[inline]
    fn fill(&mut self, rows: usize, column: impl Fn(usize, &mut [f64])) {
        for j in 0..self.x.ncols() {
            column(j, &mut self.x.col_as_slice_mut(j)[..rows]);
        }
    }
}

/// faer's default settings of the QR.
fn default_spec() -> faer::Spec<faer::linalg::qr::no_pivoting::factor::QrParams, f64> {
    Default::default()
}

/// Adjusts the conditions `c` for observations `obs`, from parameters `p0`.
pub fn solve<const K: usize>(
    c: &impl Conditions<K>,
    obs: &impl Observations<K>,
    p0: &[f64],
    opts: &Options,
) -> Result<Solution<K>, GhError> {
    let n = obs.count();
    let m = c.n_params();
    assert_eq!(p0.len(), m, "one start value per parameter");
    if n < m {
        return Err(GhError::TooFewObservations { n, m });
    }
    let mut p = p0.to_vec();
    // Zeroed by writing, here: a calloc's pages were faulted in by the first residuals'
    // parallel writes, two cores contending for them.
    let mut v = Vec::with_capacity(n);
    v.resize(n, [0.0f64; K]);
    let mut lin = Linearised::<K>::new(n, m);
    let mut last_change = f64::INFINITY;
    for iteration in 1..=opts.max_iterations {
        lin.at(c, obs, &p, &v)?;
        let step = Step::solve(&lin, opts, iteration)?;
        for j in 0..m {
            p[j] += step.dp[j];
        }
        // The largest change in units of its sd, to tell a rounding floor from divergence.
        let rounding = 1e-13;
        let mut settled = step.dp.iter().enumerate().all(|(j, d)| {
            d.abs() <= opts.tolerance * step.q_pp[j * m + j].sqrt() + rounding * p[j].abs()
        });
        let mut change = step
            .dp
            .iter()
            .enumerate()
            .map(|(j, d)| d.abs() / step.q_pp[j * m + j].sqrt())
            .fold(0.0, f64::max);
        let after = lin.residuals(&step, obs, &mut v, opts, iteration)?;
        settled &= after.settled;
        change = change.max(after.change);
        // At the rounding floor of an ill-conditioned problem the changes stop contracting a
        // few orders above `tolerance`: settled when they are below ROUNDING_FLOOR sds and
        // no longer halve.
        settled |= change <= ROUNDING_FLOOR && change > 0.5 * last_change;
        last_change = change;
        if settled {
            return Ok(lin.solution(obs, step, p, v, after.vtpv, iteration));
        }
    }
    Err(GhError::NotConverged {
        iterations: opts.max_iterations,
    })
}

/// The conditions linearised at the parameters and the adjusted observations: the design
/// `A` (row-major n x m), and per condition its misclosure w (after a step, the misclosure
/// the residuals take up), its B row and its variance q = B Sigma B^T; the weighted
/// design's column norms.
struct Linearised<const K: usize> {
    a: Vec<f64>,
    w: Vec<f64>,
    b: Vec<[f64; K]>,
    q: Vec<f64>,
    norms: Vec<f64>,
}

/// One Gauss-Newton step from the linearised conditions: the parameters' change and
/// covariance, and the equilibrated design's R (row-major m x m) and column scales.
struct Step {
    dp: Vec<f64>,
    q_pp: Vec<f64>,
    r: Vec<f64>,
    scale: Vec<f64>,
}

/// The observations' residuals after a step: v^T P v, and whether the residuals settled
/// (their largest change in units of their sds).
struct AfterStep {
    vtpv: f64,
    settled: bool,
    change: f64,
}

impl<const K: usize> Linearised<K> {
    fn new(n: usize, m: usize) -> Self {
        Linearised {
            a: vec![0.0; n * m],
            w: vec![0.0; n],
            b: vec![[0.0; K]; n],
            q: vec![0.0; n],
            norms: vec![0.0; m],
        }
    }

    fn m(&self) -> usize {
        self.norms.len()
    }

    /// Linearises the conditions at `p` and the observations `l + v`: the rows in parallel,
    /// [`TASK_ROWS`] a task, the column norms' squares summed within each task and the
    /// tasks' sums added in their order (the same bits on any number of cores).
    fn at(
        &mut self,
        c: &impl Conditions<K>,
        obs: &impl Observations<K>,
        p: &[f64],
        v: &[[f64; K]],
    ) -> Result<(), GhError> {
        let m = self.m();
        let tasks: Vec<Result<Vec<f64>, usize>> = self
            .a
            .par_chunks_mut(m * TASK_ROWS)
            .zip(self.w.par_chunks_mut(TASK_ROWS))
            .zip(self.b.par_chunks_mut(TASK_ROWS))
            .zip(self.q.par_chunks_mut(TASK_ROWS))
            .enumerate()
            .map(|(task, (((a, w), b), q))| {
                let start = task * TASK_ROWS;
                let mut squares = vec![0.0; m];
                for (k, a_row) in a.chunks_exact_mut(m).enumerate() {
                    let i = start + k;
                    let (l, sigma) = obs.get(i);
                    let l0: [f64; K] = std::array::from_fn(|t| l[t] + v[i][t]);
                    let (f, bi) = c.eval(i, p, l0, a_row);
                    let qi = (0..K).fold(0.0, |acc, t| acc + (bi[t] * sigma[t]).powi(2));
                    if qi <= 0.0 || !qi.is_finite() {
                        return Err(i);
                    }
                    w[k] = (0..K).fold(f, |acc, t| acc - bi[t] * v[i][t]);
                    b[k] = bi;
                    q[k] = qi;
                    for (s, x) in squares.iter_mut().zip(&*a_row) {
                        *s += x * x / qi;
                    }
                }
                Ok(squares)
            })
            .collect();
        let mut squares = vec![0.0; m];
        for task in tasks {
            let task = task.map_err(|index| GhError::ZeroVariance { index })?;
            for (s, t) in squares.iter_mut().zip(task) {
                *s += t;
            }
        }
        for (norm, s) in self.norms.iter_mut().zip(squares) {
            *norm = s.sqrt();
        }
        Ok(())
    }

    /// The upper triangle R (row-major (m + 1) x (m + 1)) of the QR of the weighted,
    /// equilibrated design with the weighted right-hand side `-w / sqrt(q)` as its last
    /// column: each block of [`QR_BLOCK`] rows factored with the triangle of the blocks
    /// before it stacked on top; from [`SPLIT_ROWS`] rows on, the two halves' triangles at
    /// once, then the QR of the two stacked. On the calling thread and one of its own, not
    /// the pool's: faer's kernels leave the thread that ran them with the vector registers'
    /// upper halves in use, and scalar code after them on that thread ran several times
    /// slower (the next linearisation's sin and cos; docs/benchmarks.md, Adjust), so the rows
    /// are linearised on the pool and factored here, the second half on a thread that ends
    /// with it.
    fn triangle(&self, scale: &[f64]) -> Vec<f64> {
        let n = self.q.len();
        let cols = self.m() + 1;
        if n < SPLIT_ROWS {
            return self.triangle_of(scale, 0..n);
        }
        // Two halves, split at a block's boundary that depends on n alone: the same bits on
        // any number of cores.
        let half = (n / 2).div_ceil(QR_BLOCK) * QR_BLOCK;
        let (first, second) = std::thread::scope(|s| {
            let second =
                std::thread::Builder::new().spawn_scoped(s, || self.triangle_of(scale, half..n));
            let first = self.triangle_of(scale, 0..half);
            let second = match second {
                // A panic on the second thread is raised again here, as on this one.
                Ok(h) => h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)),
                // No thread to be had: this one takes the second half too, the same bits.
                Err(_) => self.triangle_of(scale, half..n),
            };
            (first, second)
        });
        let mut qr = Householder::new(2 * cols, cols);
        qr.fill(2 * cols, |j, column| {
            for i in 0..cols {
                column[i] = first[i * cols + j];
                column[cols + i] = second[i * cols + j];
            }
        });
        qr.upper(2 * cols)
    }

    /// The upper triangle of the rows `rows` of the weighted, equilibrated design with its
    /// right-hand side, a block of [`QR_BLOCK`] rows at a time.
    fn triangle_of(&self, scale: &[f64], rows: std::ops::Range<usize>) -> Vec<f64> {
        let m = self.m();
        let cols = m + 1;
        let mut r = vec![0.0; cols * cols];
        let mut qr = Householder::new(QR_BLOCK + cols, cols);
        let (from, n) = (rows.start, rows.end);
        let mut start = from;
        // The block's sqrt(q_i), formed once for all its columns.
        let mut roots = Vec::with_capacity(QR_BLOCK);
        while start < n {
            let rows = QR_BLOCK.min(n - start);
            let top = if start == from { 0 } else { cols };
            let w = &self.w[start..start + rows];
            roots.clear();
            roots.extend(self.q[start..start + rows].iter().map(|q| q.sqrt()));
            qr.fill(top + rows, |j, column| {
                let (above, below) = column.split_at_mut(top);
                for (i, x) in above.iter_mut().enumerate() {
                    *x = r[i * cols + j];
                }
                if j < m {
                    let a = self.a[start * m..(start + rows) * m].chunks_exact(m);
                    for ((x, a), root) in below.iter_mut().zip(a).zip(&roots) {
                        *x = a[j] / (root * scale[j]);
                    }
                } else {
                    for ((x, w), root) in below.iter_mut().zip(w).zip(&roots) {
                        *x = -w / root;
                    }
                }
            });
            r = qr.upper(top + rows);
            start += rows;
        }
        r
    }

    /// New residuals from the Lagrange multipliers of `step`, written into `v`; the
    /// misclosures they take up replace `w`. The rows in parallel, `v^T P v` summed within
    /// each task and the tasks' sums added in their order.
    fn residuals(
        &mut self,
        step: &Step,
        obs: &impl Observations<K>,
        v: &mut [[f64; K]],
        opts: &Options,
        iteration: usize,
    ) -> Result<AfterStep, GhError> {
        let m = step.dp.len();
        let rounding = 1e-13;
        let tasks: Vec<(bool, f64, f64)> = self
            .a
            .par_chunks(m * TASK_ROWS)
            .zip(self.w.par_chunks_mut(TASK_ROWS))
            .zip(v.par_chunks_mut(TASK_ROWS))
            .enumerate()
            .map(|(task, ((a, w), v))| {
                let start = task * TASK_ROWS;
                let mut settled = true;
                let mut change: f64 = 0.0;
                let mut vtpv = 0.0;
                for (k, a_row) in a.chunks_exact(m).enumerate() {
                    let i = start + k;
                    let (l, sigma) = obs.get(i);
                    let adp: f64 = a_row.iter().zip(&step.dp).map(|(a, d)| a * d).sum();
                    let e = w[k] + adp;
                    let lambda = -e / self.q[i];
                    let nv: [f64; K] =
                        std::array::from_fn(|t| sigma[t].powi(2) * self.b[i][t] * lambda);
                    for t in 0..K {
                        let limit = opts.tolerance * sigma[t] + rounding * l[t].abs();
                        if sigma[t] > 0.0 && (nv[t] - v[k][t]).abs() > limit {
                            settled = false;
                            change = change.max((nv[t] - v[k][t]).abs() / sigma[t]);
                        }
                    }
                    v[k] = nv;
                    w[k] = -e;
                    vtpv += e * e / self.q[i];
                }
                (settled, change, vtpv)
            })
            .collect();
        let (mut settled, mut change, mut vtpv) = (true, 0.0f64, -0.0);
        for (s, c, t) in tasks {
            settled &= s;
            change = change.max(c);
            vtpv += t;
        }
        if !vtpv.is_finite() {
            return Err(GhError::NonFinite { iteration });
        }
        Ok(AfterStep {
            vtpv,
            settled,
            change,
        })
    }

    /// Each condition's redundancy 1 - h_i, with the leverage h_i = || R^-T a~_i ||^2 of
    /// the equilibrated, weighted design row, and its w-test (`w` holding the misclosures);
    /// and the parts of its variance q_i, (b_it sigma_it)^2. In one pass on the pool.
    fn redundancy(
        &self,
        step: &Step,
        obs: &impl Observations<K>,
    ) -> (Vec<f64>, Vec<f64>, Vec<[f64; K]>) {
        let n = self.q.len();
        let m = step.dp.len();
        let r = &step.r;
        let (mut redundancy, mut w_test) = (vec![0.0; n], vec![0.0; n]);
        let mut q_parts = vec![[0.0; K]; n];
        redundancy
            .par_chunks_mut(TASK_ROWS)
            .zip(w_test.par_chunks_mut(TASK_ROWS))
            .zip(q_parts.par_chunks_mut(TASK_ROWS))
            .enumerate()
            .for_each(|(task, ((redundancy, w_test), q_parts))| {
                let mut z = vec![0.0; m];
                for (k, ((ri, wi), qi)) in redundancy
                    .iter_mut()
                    .zip(w_test.iter_mut())
                    .zip(q_parts.iter_mut())
                    .enumerate()
                {
                    let i = task * TASK_ROWS + k;
                    let (row, root) = (&self.a[i * m..(i + 1) * m], self.q[i].sqrt());
                    for k in 0..m {
                        // The weighted, equilibrated design, a_ik / (sqrt(q_i) scale_k).
                        let mut s = row[k] / (root * step.scale[k]);
                        for t in 0..k {
                            s -= r[t * m + k] * z[t];
                        }
                        z[k] = s / r[k * m + k];
                    }
                    let h: f64 = z.iter().map(|x| x * x).sum();
                    *ri = (1.0 - h).max(0.0);
                    *wi = if *ri > 1e-9 {
                        self.w[i] / (self.q[i] * *ri).sqrt()
                    } else {
                        0.0
                    };
                    let (bi, sigma) = (self.b[i], obs.get(i).1);
                    *qi = std::array::from_fn(|t| (bi[t] * sigma[t]).powi(2));
                }
            });
        (redundancy, w_test, q_parts)
    }

    /// The solution at the settled step: the linearisation's vectors become its own.
    fn solution(
        self,
        obs: &impl Observations<K>,
        step: Step,
        p: Vec<f64>,
        v: Vec<[f64; K]>,
        vtpv: f64,
        iterations: usize,
    ) -> Solution<K> {
        let (redundancy, w_test, q_parts) = self.redundancy(&step, obs);
        let n = self.q.len();
        Solution {
            p,
            q_pp: step.q_pp,
            v,
            misclosure: self.w,
            q_ww: self.q,
            q_parts,
            redundancy,
            w_test,
            vtpv,
            dof: n - step.dp.len(),
            iterations,
            a: self.a,
            b: self.b,
        }
    }
}

impl Step {
    /// The QR of the equilibrated design with its right-hand side ([`Linearised::triangle`]):
    /// the step, and the parameters' cofactor matrix Q_pp = D^-1 R^-1 R^-T D^-1.
    fn solve<const K: usize>(
        lin: &Linearised<K>,
        opts: &Options,
        iteration: usize,
    ) -> Result<Step, GhError> {
        let m = lin.m();
        let cols = m + 1;
        for (j, norm) in lin.norms.iter().enumerate() {
            if *norm == 0.0 || !norm.is_finite() {
                return Err(GhError::NotEstimable { index: j });
            }
        }
        let scale = lin.norms.clone();
        let augmented = lin.triangle(&scale);
        let mut r = vec![0.0; m * m];
        for i in 0..m {
            for j in i..m {
                r[i * m + j] = augmented[i * cols + j];
            }
        }
        for j in 0..m {
            let diag = r[j * m + j].abs();
            if diag.is_nan() || diag <= opts.rank_tolerance {
                return Err(GhError::NotEstimable { index: j });
            }
        }
        let r_inv = invert_upper(&r, m);
        // R dp~ = Q^T rhs, the triangle's last column.
        let dp: Vec<f64> = (0..m)
            .map(|i| {
                let x: f64 = (i..m)
                    .map(|k| r_inv[i * m + k] * augmented[k * cols + m])
                    .sum();
                x / scale[i]
            })
            .collect();
        if dp.iter().any(|x| !x.is_finite()) {
            return Err(GhError::NonFinite { iteration });
        }
        let mut q_pp = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                let s: f64 = (i.max(j)..m)
                    .map(|k| r_inv[i * m + k] * r_inv[j * m + k])
                    .sum();
                q_pp[i * m + j] = s / (scale[i] * scale[j]);
            }
        }
        Ok(Step { dp, q_pp, r, scale })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = p0 + p1 x; l = (x, y).
    struct Line;
    impl Conditions for Line {
        fn n_params(&self) -> usize {
            2
        }
        fn eval(&self, _i: usize, p: &[f64], l: [f64; 2], a: &mut [f64]) -> (f64, [f64; 2]) {
            a[0] = -1.0;
            a[1] = -l[0];
            (l[1] - p[0] - p[1] * l[0], [-p[1], 1.0])
        }
    }

    #[test]
    fn straight_line_through_exact_points_and_residual_invariants() {
        let x: Vec<f64> = (0..20).map(f64::from).collect();
        let noise = [
            0.3, -0.1, 0.2, -0.4, 0.1, 0.0, -0.2, 0.5, -0.3, 0.1, 0.2, -0.1, 0.0, 0.3, -0.2, -0.1,
            0.4, -0.5, 0.2, 0.1,
        ];
        let l: Vec<[f64; 2]> = x
            .iter()
            .zip(noise)
            .map(|(&x, e)| [x, 2.0 + 0.5 * x + e])
            .collect();
        let sigma = vec![[0.0, 1.0]; 20];
        let s = solve(
            &Line,
            &Held::new(&l, &sigma),
            &[0.0, 0.0],
            &Options::default(),
        )
        .expect("solves");
        // Residuals are orthogonal to the design: sum v = 0 and sum x v = 0.
        let sv: f64 = s.v.iter().map(|v| v[1]).sum();
        let sxv: f64 = s.v.iter().zip(&x).map(|(v, x)| v[1] * x).sum();
        assert!(sv.abs() < 1e-10 && sxv.abs() < 1e-9, "{sv} {sxv}");
        // Redundancy numbers add up to the degrees of freedom.
        let rsum: f64 = s.redundancy.iter().sum();
        assert!((rsum - 18.0).abs() < 1e-9, "{rsum}");
        assert_eq!(s.dof, 18);
        assert!(s.iterations <= 3);
    }

    /// From [`SPLIT_ROWS`] rows on, the triangle is taken in two halves at once: the same R
    /// (up to its rows' signs) as the blocks taken one after the other, to rounding, and
    /// the same at any number of rows about the split.
    #[test]
    fn the_triangle_in_two_halves_is_the_triangle_in_one() {
        for n in [SPLIT_ROWS, SPLIT_ROWS + 1, 3 * SPLIT_ROWS + 517] {
            let l: Vec<[f64; 2]> = (0..n)
                .map(|i| {
                    let x = i as f64 / n as f64;
                    [x, 1.0 + 3.0 * x + 0.01 * (i as f64 * 0.7).sin()]
                })
                .collect();
            let sigma: Vec<[f64; 2]> = (0..n).map(|i| [0.0, 1.0 + (i % 7) as f64]).collect();
            let mut lin = Linearised::<2>::new(n, 2);
            let v = vec![[0.0; 2]; n];
            lin.at(&Line, &Held::new(&l, &sigma), &[0.5, 2.0], &v)
                .expect("linearises");
            let scale = lin.norms.clone();
            let (split, whole) = (lin.triangle(&scale), lin.triangle_of(&scale, 0..n));
            for i in 0..3 {
                let sign = split[i * 3 + i].signum() * whole[i * 3 + i].signum();
                for j in i..3 {
                    let (a, b) = (split[i * 3 + j], sign * whole[i * 3 + j]);
                    assert!(
                        (a - b).abs() <= 1e-12 * whole[i * 3 + i].abs().max(1.0),
                        "n {n}: R[{i}][{j}] {a} against {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn collinear_parameter_is_named() {
        struct Twice;
        impl Conditions for Twice {
            fn n_params(&self) -> usize {
                2
            }
            fn eval(&self, _i: usize, p: &[f64], l: [f64; 2], a: &mut [f64]) -> (f64, [f64; 2]) {
                a[0] = -l[0];
                a[1] = -2.0 * l[0];
                (
                    l[1] - (p[0] + 2.0 * p[1]) * l[0],
                    [-(p[0] + 2.0 * p[1]), 1.0],
                )
            }
        }
        let l: Vec<[f64; 2]> = (1..10)
            .map(|i| [f64::from(i), 3.0 * f64::from(i)])
            .collect();
        let e = solve(
            &Twice,
            &Held::new(&l, &[[0.0, 1.0]; 9]),
            &[0.0, 0.0],
            &Options::default(),
        )
        .expect_err("rank deficient");
        assert_eq!(e, GhError::NotEstimable { index: 1 });
    }
}
