//! Translation runs of a [`VectorOperator`]: consecutive rows of consecutive nodes that share a
//! stencil and whose columns all shift by one from row to row (a lattice row away from
//! boundaries and switched nodes). Over a run, K u is a sum of shifted axpys; evaluated
//! `CHUNK` rows at a time on component arrays (SoA), every load is contiguous, the column
//! list is read once per chunk instead of once per row, and the lane loops become SIMD. Rows
//! outside runs (and run tails) use the operator's row product.

use rayon::prelude::*;

use super::VectorOperator;

/// Rows evaluated together inside a run.
const CHUNK: usize = 8;
/// Rows per parallel task; runs are split at its multiples so tasks own disjoint outputs.
const BLOCK: usize = 256;

/// The runs of one operator, grouped by blocks of `BLOCK` rows.
#[derive(Debug, Clone, PartialEq)]
pub struct RowRuns {
    /// Runs as (first row, length), in row order, covering every row once.
    runs: Vec<(u32, u32)>,
    /// Block b's runs are runs[block_first[b]..block_first[b + 1]].
    block_first: Vec<usize>,
}

impl RowRuns {
    pub fn new<const D: usize>(op: &VectorOperator<D>) -> Self {
        let shifted = |r: usize| {
            let (a, b) = (
                op.offsets[r]..op.offsets[r + 1],
                op.offsets[r + 1]..op.offsets[r + 2],
            );
            op.rows[r + 1] == op.rows[r] + 1
                && op.stencil_of[r + 1] == op.stencil_of[r]
                && a.len() == b.len()
                && op.columns[a]
                    .iter()
                    .zip(&op.columns[b])
                    .all(|(&j, &k)| k == j + 1)
        };
        let n = op.rows.len();
        let mut runs = Vec::new();
        let mut block_first = Vec::with_capacity(n / BLOCK + 2);
        let mut r = 0;
        while r < n {
            if r % BLOCK == 0 {
                block_first.push(runs.len());
            }
            let block_end = (r / BLOCK + 1) * BLOCK;
            let mut end = r + 1;
            while end < n.min(block_end) && shifted(end - 1) {
                end += 1;
            }
            runs.push((r as u32, (end - r) as u32));
            r = end;
        }
        block_first.push(runs.len());
        RowRuns { runs, block_first }
    }

    /// Fraction of rows that lie in full chunks of a run (the fast path).
    pub fn chunked_fraction(&self) -> f64 {
        let rows: usize = self.runs.iter().map(|&(_, len)| len as usize).sum();
        let fast: usize = self
            .runs
            .iter()
            .map(|&(_, len)| len as usize / CHUNK * CHUNK)
            .sum();
        fast as f64 / rows.max(1) as f64
    }

    /// out[r] = Σ_j K_rj u_j for every row r with `wanted(r)` (other entries are left alone or
    /// overwritten), u given by components (`u[l][j]`). Parallel over blocks, no allocation;
    /// deterministic (each row's sum has a fixed order for a given CPU).
    pub fn apply<const D: usize>(
        &self,
        op: &VectorOperator<D>,
        u: [&[f64]; D],
        wanted: impl Fn(usize) -> bool + Sync,
        out: &mut [[f64; D]],
    ) {
        self.apply_with(Kernel::fastest(), op, u, wanted, out);
    }

    /// [`Self::apply`] with a given chunk kernel (it must be supported by this CPU).
    pub fn apply_with<const D: usize>(
        &self,
        kernel: Kernel,
        op: &VectorOperator<D>,
        u: [&[f64]; D],
        wanted: impl Fn(usize) -> bool + Sync,
        out: &mut [[f64; D]],
    ) {
        assert!(
            Kernel::supported().contains(&kernel),
            "{kernel:?} on this CPU"
        );
        out.par_chunks_mut(BLOCK)
            .enumerate()
            .for_each(|(block, out)| {
                let runs = &self.runs[self.block_first[block]..self.block_first[block + 1]];
                let base = block * BLOCK;
                match kernel {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: the CPU supports AVX-512F (asserted above).
                    Kernel::Avx512 => unsafe { block_avx512(op, runs, base, u, &wanted, out) },
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: the CPU supports AVX2 and FMA (asserted above).
                    Kernel::Avx2Fma => unsafe { block_avx2(op, runs, base, u, &wanted, out) },
                    _ => block_portable(op, runs, base, u, &wanted, out, chunk_product),
                }
            });
    }
}

/// The chunk products this build has: portable code, AVX2 with FMA (two 4-lane registers per
/// 8 rows) and AVX-512 (one register). They sum the same terms in the same order; the fused
/// ones round each product into its sum once, so results differ in the last bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    Portable,
    Avx2Fma,
    Avx512,
}

impl Kernel {
    /// The kernels this CPU runs, slowest first.
    pub fn supported() -> Vec<Kernel> {
        let mut kernels = vec![Kernel::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                kernels.push(Kernel::Avx2Fma);
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                kernels.push(Kernel::Avx512);
            }
        }
        kernels
    }

    pub fn fastest() -> Kernel {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Kernel::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Kernel::Avx2Fma;
            }
        }
        Kernel::Portable
    }
}

/// Defines `block_portable` with its chunk product compiled for a target feature set: the
/// kernel runs in 4 partial accumulators for a scalar operator (D = 1), so FMA chains stay
/// independent, and in one per (k, l) term otherwise.
macro_rules! simd_block {
    ($(#[$doc:meta])* $name:ident, $features:literal, $kernel:ident) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $name<const D: usize>(
            op: &VectorOperator<D>,
            runs: &[(u32, u32)],
            base: usize,
            u: [&[f64]; D],
            wanted: &impl Fn(usize) -> bool,
            out: &mut [[f64; D]],
        ) {
            block_portable(op, runs, base, u, wanted, out, |op, run, shift, u, chunk| {
                // SAFETY: this function only runs where its target features are present
                // (`Kernel::fastest`, `Kernel::supported`).
                unsafe {
                    if D == 1 {
                        $kernel::<D, 4>(op, run, shift, u, chunk)
                    } else {
                        $kernel::<D, 1>(op, run, shift, u, chunk)
                    }
                }
            })
        }
    };
}

simd_block!(
    /// `block_portable` with the chunk product in AVX2 + FMA registers (see `chunk_product_fma`).
    block_avx2,
    "avx,avx2,fma",
    chunk_product_fma
);
simd_block!(
    /// `block_portable` with the chunk product in AVX-512 registers (one register per 8 rows).
    block_avx512,
    "avx512f",
    chunk_product_avx512
);

#[inline(always)]
fn block_portable<const D: usize>(
    op: &VectorOperator<D>,
    runs: &[(u32, u32)],
    base: usize,
    u: [&[f64]; D],
    wanted: &impl Fn(usize) -> bool,
    out: &mut [[f64; D]],
    chunk_product: impl Fn(&VectorOperator<D>, usize, usize, [&[f64]; D], &mut [[f64; D]; CHUNK]),
) {
    let component = |j: usize| -> [f64; D] { std::array::from_fn(|l| u[l][j]) };
    for &(first, len) in runs {
        let (first, len) = (first as usize, len as usize);
        let mut r = first;
        while r + CHUNK <= first + len {
            if (r..r + CHUNK).any(wanted) {
                let chunk: &mut [[f64; D]; CHUNK] = (&mut out[r - base..r - base + CHUNK])
                    .try_into()
                    .expect("a chunk of CHUNK rows");
                chunk_product(op, first, r - first, u, chunk);
            }
            r += CHUNK;
        }
        for r in r..first + len {
            if wanted(r) {
                out[r - base] = op.apply_row_with(r, component);
            }
        }
    }
}

/// Rows r … r + CHUNK − 1 of the run starting at row `run`, r = run + `shift`:
/// out[t] = Σ_e K_e u(c_e + shift + t), c_e the columns of the run's first row (read from
/// there for the whole run: one cache-resident column list instead of one per chunk).
#[inline(always)]
fn chunk_product<const D: usize>(
    op: &VectorOperator<D>,
    run: usize,
    shift: usize,
    u: [&[f64]; D],
    out: &mut [[f64; D]; CHUNK],
) {
    let columns = &op.columns[op.offsets[run]..op.offsets[run + 1]];
    let blocks = op.row_blocks(run);
    let mut acc = [[0.0; CHUNK]; D];
    for (&c, block) in columns.iter().zip(blocks) {
        let c = c as usize + shift;
        for l in 0..D {
            let lane = &u[l][c..c + CHUNK];
            for k in 0..D {
                let w = block[k][l];
                for t in 0..CHUNK {
                    acc[k][t] += w * lane[t];
                }
            }
        }
    }
    for (t, o) in out.iter_mut().enumerate() {
        *o = std::array::from_fn(|k| acc[k][t]);
    }
}

/// `chunk_product` in AVX2 registers with fused multiply-adds. Two 4-lane registers hold a
/// component's 8 rows; weights are broadcast. Each (k, l) term has its own accumulators, and
/// columns go round-robin to `P` partial sums, so the FMA chains are independent (the loop runs
/// at FMA throughput, not latency); they are summed at the end. Rounding differs from the
/// portable path in the last bits.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
unsafe fn chunk_product_fma<const D: usize, const P: usize>(
    op: &VectorOperator<D>,
    run: usize,
    shift: usize,
    u: [&[f64]; D],
    out: &mut [[f64; D]; CHUNK],
) {
    use std::arch::x86_64::*;
    const _: () = assert!(CHUNK == 8);
    let columns = &op.columns[op.offsets[run]..op.offsets[run + 1]];
    let blocks = op.row_blocks(run);
    let mut acc = [[[[_mm256_setzero_pd(); 2]; D]; D]; P];
    // A macro, not a closure: a closure taking the accumulators by reference keeps them in
    // memory (measured: a store per FMA).
    macro_rules! accumulate {
        ($acc:expr, $c:expr, $block:expr) => {
            let c = $c as usize + shift;
            for l in 0..D {
                let lane: &[f64; CHUNK] = u[l][c..c + CHUNK].try_into().expect("8 rows");
                // SAFETY: `lane` holds 8 f64, read as two unaligned groups of 4.
                let (lo, hi) = unsafe {
                    (
                        _mm256_loadu_pd(lane.as_ptr()),
                        _mm256_loadu_pd(lane.as_ptr().add(4)),
                    )
                };
                for k in 0..D {
                    let w = _mm256_set1_pd($block[k][l]);
                    $acc[k][l][0] = _mm256_fmadd_pd(w, lo, $acc[k][l][0]);
                    $acc[k][l][1] = _mm256_fmadd_pd(w, hi, $acc[k][l][1]);
                }
            }
        };
    }
    let (column_groups, block_groups) = (columns.chunks_exact(P), blocks.chunks_exact(P));
    for (&c, block) in column_groups
        .remainder()
        .iter()
        .zip(block_groups.remainder())
    {
        accumulate!(acc[0], c, block);
    }
    for (cs, bs) in column_groups.zip(block_groups) {
        for p in 0..P {
            accumulate!(acc[p], cs[p], bs[p]);
        }
    }
    let mut rows = [[0.0; CHUNK]; D];
    for k in 0..D {
        let [mut lo, mut hi] = [_mm256_setzero_pd(); 2];
        for term in acc.iter().flat_map(|partial| &partial[k]) {
            lo = _mm256_add_pd(lo, term[0]);
            hi = _mm256_add_pd(hi, term[1]);
        }
        // SAFETY: rows[k] holds 8 f64, written as two unaligned groups of 4.
        unsafe {
            _mm256_storeu_pd(rows[k].as_mut_ptr(), lo);
            _mm256_storeu_pd(rows[k].as_mut_ptr().add(4), hi);
        }
    }
    for (t, o) in out.iter_mut().enumerate() {
        *o = std::array::from_fn(|k| rows[k][t]);
    }
}

/// `chunk_product_fma` with one AVX-512 register per component's 8 rows.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn chunk_product_avx512<const D: usize, const P: usize>(
    op: &VectorOperator<D>,
    run: usize,
    shift: usize,
    u: [&[f64]; D],
    out: &mut [[f64; D]; CHUNK],
) {
    use std::arch::x86_64::*;
    let columns = &op.columns[op.offsets[run]..op.offsets[run + 1]];
    let blocks = op.row_blocks(run);
    let mut acc = [[[_mm512_setzero_pd(); D]; D]; P];
    // A macro, not a closure (see `chunk_product_fma`).
    macro_rules! accumulate {
        ($acc:expr, $c:expr, $block:expr) => {
            let c = $c as usize + shift;
            for l in 0..D {
                let lane: &[f64; CHUNK] = u[l][c..c + CHUNK].try_into().expect("8 rows");
                // SAFETY: `lane` holds 8 f64, read unaligned.
                let values = unsafe { _mm512_loadu_pd(lane.as_ptr()) };
                for k in 0..D {
                    $acc[k][l] = _mm512_fmadd_pd(_mm512_set1_pd($block[k][l]), values, $acc[k][l]);
                }
            }
        };
    }
    let (column_groups, block_groups) = (columns.chunks_exact(P), blocks.chunks_exact(P));
    for (&c, block) in column_groups
        .remainder()
        .iter()
        .zip(block_groups.remainder())
    {
        accumulate!(acc[0], c, block);
    }
    for (cs, bs) in column_groups.zip(block_groups) {
        for p in 0..P {
            accumulate!(acc[p], cs[p], bs[p]);
        }
    }
    let mut rows = [[0.0; CHUNK]; D];
    for k in 0..D {
        let mut sum = _mm512_setzero_pd();
        for &term in acc.iter().flat_map(|partial| &partial[k]) {
            sum = _mm512_add_pd(sum, term);
        }
        // SAFETY: rows[k] holds 8 f64, written unaligned.
        unsafe { _mm512_storeu_pd(rows[k].as_mut_ptr(), sum) };
    }
    for (t, o) in out.iter_mut().enumerate() {
        *o = std::array::from_fn(|k| rows[k][t]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::family::Families;
    use crate::discretization::grid::Lattice;
    use crate::scene::Solid;
    use crate::scheme::wls;

    #[test]
    fn runs_give_the_row_products() {
        // A 2D lattice whose WLS rows mix interior runs, boundary rows and a gap.
        let solid = Solid::Box {
            min: vec![0.0, 0.0],
            max: vec![40.0, 11.0],
        };
        let lattice = Lattice::<2>::build(&solid, 1.0, [0.0, 0.0], 1);
        let horizon = 3.0;
        let families = Families::build(&lattice.positions, horizon * (1.0 + 1e-9));
        let rows: Vec<u32> = (0..lattice.positions.len() as u32)
            .filter(|&i| i % 97 != 5)
            .collect();
        let basis = wls::Basis::new(2, 2);
        let l = wls::bond_l(&basis, 1.0, horizon, Default::default());
        let op =
            wls::elasticity_operator(&rows, &lattice.positions, &families, &basis, &l, horizon, 3)
                .unwrap();
        let runs = RowRuns::new(&op);
        assert!(runs.chunked_fraction() > 0.3, "{}", runs.chunked_fraction());
        let n = lattice.positions.len();
        let u: Vec<[f64; 2]> = (0..n)
            .map(|i| [(i as f64 * 0.37).sin(), (i as f64 * 0.11).cos()])
            .collect();
        let components: [Vec<f64>; 2] = std::array::from_fn(|l| u.iter().map(|v| v[l]).collect());
        let mut reference = vec![[0.0; 2]; rows.len()];
        op.apply_rows(&u, &mut reference);
        let scale = reference
            .iter()
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        for kernel in Kernel::supported() {
            let mut fast = vec![[f64::NAN; 2]; rows.len()];
            runs.apply_with(
                kernel,
                &op,
                [&components[0], &components[1]],
                |_| true,
                &mut fast,
            );
            for (a, b) in fast.iter().zip(&reference) {
                for k in 0..2 {
                    assert!(
                        (a[k] - b[k]).abs() <= 1e-12 * scale,
                        "{kernel:?}: {a:?} vs {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn scalar_runs_give_the_per_row_diffusion_operator() {
        // WLS diffusion in stencil form (D = 1 blocks, 4 partial sums in the fused kernels)
        // against the per-row operator: same values up to rounding, on a 3D box with a gap.
        let solid = Solid::Box {
            min: vec![0.0; 3],
            max: vec![23.0, 6.0, 6.0],
        };
        let lattice = Lattice::<3>::build(&solid, 1.0, [0.0, 0.0], 1);
        let horizon = 2.0;
        let families = Families::build(&lattice.positions, horizon * (1.0 + 1e-9));
        let rows: Vec<u32> = (0..lattice.positions.len() as u32)
            .filter(|&i| i % 53 != 7)
            .collect();
        let basis = wls::Basis::new(3, 2);
        let l = wls::diffusion_l(&basis, 1.0, 1.0, horizon, Default::default());
        let positions = &lattice.positions;
        let per_row =
            wls::diffusion_operator(&rows, positions, &families, &basis, &l, horizon, 3).unwrap();
        let stenciled =
            wls::diffusion_stencil_operator(&rows, positions, &families, &basis, &l, horizon, 3)
                .unwrap();
        assert!(stenciled.stencil_count() < rows.len() / 4);
        let runs = RowRuns::new(&stenciled);
        assert!(runs.chunked_fraction() > 0.3, "{}", runs.chunked_fraction());
        let values: Vec<f64> = positions
            .iter()
            .enumerate()
            .map(|(i, x)| (i as f64 * 0.37).sin() + x[0] * x[1] * 0.01)
            .collect();
        let mut reference = vec![0.0; rows.len()];
        per_row.apply_rows(&values, &mut reference);
        let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for kernel in Kernel::supported() {
            let mut fast = vec![[f64::NAN]; rows.len()];
            runs.apply_with(kernel, &stenciled, [&values], |_| true, &mut fast);
            for (a, b) in fast.iter().zip(&reference) {
                assert!(
                    (a[0] - b).abs() <= 1e-11 * scale,
                    "{kernel:?}: {a:?} vs {b}"
                );
            }
        }
    }
}
