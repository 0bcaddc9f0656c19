//! `cargo bench`: profiles the core kernels on a 6-joint standard-DH robot (the HSR JR680
//! geometry of the paper's Table I) at m = 100, 1 000, 10 000 samples (and 100 000 poses for
//! forward kinematics).

use _robocal::fixtures::hsr_jr680;
use _robocal::kinematics::Chain;
use _robocal::measurement::{sigma_residuals, Batch, Measurement};
use _robocal::sigma::merwe_sigma_points;
use _robocal::solve::{fold_products, solve_damped, sparse_gram, Csr, DampedQr, Damping};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;

const SIZES: [usize; 3] = [100, 1_000, 10_000];

/// The HSR JR680 as calibrated: every DH parameter slightly off nominal, so no link parameter
/// is exactly zero (zero-valued constant transforms are skipped by the core).
fn robot() -> (Chain, Vec<f64>) {
    let (chain, mut p) = hsr_jr680();
    for j in 0..6 {
        let (alpha, a, d, theta, _) = chain.layout().joint(j);
        for (k, idx) in [alpha, a, d, theta].into_iter().enumerate() {
            p[idx] += 1e-3 * (((j * 4 + k) as f64) * 0.618_033_988_75).fract();
        }
    }
    (chain, p)
}

/// Deterministic joint configurations spread over ±1 rad around a working pose.
fn configurations(m: usize) -> Vec<f64> {
    let centre = [0.1, -1.0, 3.5, -2.8, 0.7, 1.0];
    (0..m * 6).map(|k| centre[k % 6] + ((k as f64) * 0.618_033_988_75).fract() * 2.0 - 1.0).collect()
}

/// The paper's cable parameter set: 24 DH + tool point (3) + anchor (3) + sensor zero (1).
fn cable_columns(chain: &Chain) -> Vec<usize> {
    let s = chain.layout().sensor();
    let mut cols: Vec<usize> = (0..6).flat_map(|j| (0..4).map(move |k| 5 * j + k)).collect();
    cols.extend(chain.layout().tool()..chain.layout().tool() + 3);
    cols.extend(s..s + 4);
    cols
}

fn bench_fk(c: &mut Criterion) {
    let (chain, p) = robot();
    let mut group = c.benchmark_group("fk_batch");
    for m in SIZES.into_iter().chain([100_000]) {
        let q = configurations(m);
        group.throughput(Throughput::Elements(m as u64));
        group.bench_with_input(BenchmarkId::from_parameter(m), &q, |b, q| b.iter(|| chain.fk_batch(black_box(&p), q, true).unwrap()));
    }
    group.finish();
}

/// One residual evaluation of the cable model: what a least-squares iteration and every
/// candidate of a diagnosis evaluate (D1 has 2017 samples).
fn bench_cable_residuals(c: &mut Criterion) {
    let (chain, p) = robot();
    let mut group = c.benchmark_group("cable_residuals");
    for m in SIZES {
        let q = configurations(m);
        let y = Batch::new(&chain, Measurement::Cable, &p, &q, None).unwrap().predict();
        group.throughput(Throughput::Elements(m as u64));
        group.bench_with_input(BenchmarkId::from_parameter(m), &q, |b, q| {
            b.iter(|| Batch::new(&chain, Measurement::Cable, black_box(&p), q, Some(&y)).unwrap().residuals().unwrap())
        });
    }
    group.finish();
}

fn bench_cable_jacobian(c: &mut Criterion) {
    let (chain, p) = robot();
    let cols = cable_columns(&chain);
    let mut group = c.benchmark_group("cable_jacobian_31");
    for m in SIZES {
        let q = configurations(m);
        group.throughput(Throughput::Elements(m as u64));
        group.bench_with_input(BenchmarkId::from_parameter(m), &q, |b, q| {
            b.iter(|| Batch::new(&chain, Measurement::Cable, black_box(&p), q, None).unwrap().jacobian(&cols).unwrap())
        });
    }
    group.finish();
}

fn bench_sigma(c: &mut Criterion) {
    let (chain, p) = robot();
    let cols = cable_columns(&chain);
    let n = cols.len();
    let x: Vec<f64> = cols.iter().map(|&k| p[k]).collect();
    let cov: Vec<f64> = (0..n * n).map(|k| if k % (n + 1) == 0 { 1e-4 } else { 0.0 }).collect();
    let (sigmas, _, _) = merwe_sigma_points(&x, &cov, 1e-3, 2.0, 0.0).unwrap();
    let mut group = c.benchmark_group("sigma_residuals_63x");
    group.sample_size(10);
    for m in SIZES {
        let q = configurations(m);
        let y = Batch::new(&chain, Measurement::Cable, &p, &q, None).unwrap().predict();
        group.throughput(Throughput::Elements((m * (2 * n + 1)) as u64));
        group.bench_with_input(BenchmarkId::from_parameter(m), &q, |b, q| {
            let batch = Batch::new(&chain, Measurement::Cable, &p, q, Some(&y)).unwrap();
            b.iter(|| sigma_residuals(&batch, &cols, black_box(&sigmas)).unwrap())
        });
    }
    group.finish();
}

fn bench_solve(c: &mut Criterion) {
    let mut group = c.benchmark_group("solve_damped");
    for n in [24usize, 31, 60] {
        for m in SIZES {
            let j: Vec<f64> = (0..m * n).map(|k| ((k as f64) * 0.754_877_666).fract() - 0.5).collect();
            let r: Vec<f64> = (0..m).map(|k| ((k as f64) * 0.569_840_29).fract()).collect();
            group.bench_with_input(BenchmarkId::new(format!("n{n}"), m), &j, |b, j| {
                b.iter(|| solve_damped(black_box(j), &r, m, n, 1e-3, Damping::Marquardt).unwrap())
            });
        }
    }
    group.finish();
}

/// The LM's factorisation of an ill-conditioned dense Jacobian (D1's: 24 columns): `J = Q·R`
/// and `Qᵀr`.
fn bench_damped_qr(c: &mut Criterion) {
    let mut group = c.benchmark_group("damped_qr");
    let n = 24usize;
    for m in SIZES {
        let j: Vec<f64> = (0..m * n).map(|k| ((k as f64) * 0.754_877_666).fract() - 0.5).collect();
        let r: Vec<f64> = (0..m).map(|k| ((k as f64) * 0.569_840_29).fract()).collect();
        group.bench_with_input(BenchmarkId::new(format!("n{n}"), m), &j, |b, j| {
            b.iter(|| DampedQr::new(black_box(j), m, n).unwrap().project(&r).unwrap())
        });
        // The factorisation DampedQr used before: faer's blocked QR (R only, no Qᵀr).
        group.bench_with_input(BenchmarkId::new(format!("faer_qr_n{n}"), m), &j, |b, j| {
            b.iter(|| faer::MatRef::from_row_major_slice(black_box(j), m, n).qr())
        });
    }
    group.finish();
}

/// A diagnosis' sparse Jacobian as CSR `(indptr, indices, data, ncols)`: 3 rows a sample (a
/// tracker's position), 28 dense columns (the geometry and the set-up) and five joint maps of
/// 120 B-spline coefficients, four consecutive ones a row, at a coefficient that moves slowly
/// along the samples (a path) — the layout of UR10 series A with five maps (36 000 rows, 51
/// entries a row).
fn five_map_rows(samples: usize) -> (Vec<usize>, Vec<usize>, Vec<f64>, usize) {
    let (dense, maps, width) = (28usize, 5usize, 120usize);
    let (mut indptr, mut indices, mut data) = (vec![0usize], Vec::new(), Vec::new());
    for row in 0..3 * samples {
        indices.extend(0..dense);
        for map in 0..maps {
            let at = ((row / 3) * (map + 1) / 7) % (width - 4);
            indices.extend((0..4).map(|t| dense + map * width + at + t));
        }
        data.extend((data.len()..indices.len()).map(|k| ((k as f64) * 0.618_033_988_75).fract() - 0.5));
        indptr.push(indices.len());
    }
    (indptr, indices, data, dense + maps * width)
}

/// `JᵀJ` of that Jacobian.
fn bench_sparse_gram(c: &mut Criterion) {
    let mut group = c.benchmark_group("sparse_gram");
    for samples in [1_000usize, 12_000] {
        let (indptr, indices, data, ncols) = five_map_rows(samples);
        group.throughput(Throughput::Elements(indices.len() as u64));
        group.bench_with_input(BenchmarkId::new("ur10_five_maps", samples), &(indptr, indices, data), |b, (p, i, d)| {
            b.iter(|| sparse_gram(black_box(p), i, d, ncols).unwrap())
        });
    }
    group.finish();
}

/// A map screening's per-fold blocks on that layout: a sixth joint's map candidate (120
/// coefficients, four a row) against the Jacobian, over two labellings of ten folds (random and
/// blocked cross-validation).
fn bench_fold_products(c: &mut Criterion) {
    let mut group = c.benchmark_group("fold_products");
    for samples in [1_000usize, 12_000] {
        let (indptr, indices, data, ncols) = five_map_rows(samples);
        let rows = indptr.len() - 1;
        let c_indptr: Vec<usize> = (0..=rows).map(|i| 4 * i).collect();
        let c_indices: Vec<usize> = (0..rows).flat_map(|i| (0..4).map(move |t| (i / 3) * 116 / (rows / 3) + t)).collect();
        let c_data: Vec<f64> = (0..c_indices.len()).map(|k| ((k as f64) * 0.414_213_562_37).fract() - 0.5).collect();
        let r: Vec<f64> = (0..rows).map(|i| ((i as f64) * 0.732_050_807_57).fract() - 0.5).collect();
        let labels = vec![(0..rows).map(|i| (i / 3 * 7919) % 10).collect::<Vec<_>>(), (0..rows).map(|i| i * 10 / rows).collect()];
        group.throughput(Throughput::Elements(indices.len() as u64));
        group.bench_function(BenchmarkId::new("ur10_sixth_map", samples), |b| {
            let cand = Csr { indptr: &c_indptr, indices: &c_indices, data: &c_data, ncols: 120 };
            let j = Csr { indptr: &indptr, indices: &indices, data: &data, ncols };
            b.iter(|| fold_products(black_box(cand), j, &r, &labels, &[10, 10]).unwrap())
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(2));
    targets = bench_fk, bench_cable_residuals, bench_cable_jacobian, bench_sigma, bench_solve, bench_damped_qr, bench_sparse_gram, bench_fold_products
}
criterion_main!(benches);
