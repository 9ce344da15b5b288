//! Measures for comparing two wind fields on the same cells (the OpenFOAM cross-check,
//! docs/wind-cfd.md).

/// Pearson's correlation coefficient of two equally long samples (say, the wind speed of
/// two fields at the same cells): 1 when one is an increasing linear function of the other.
/// NaN when either sample is constant or the samples are empty.
///
/// # Panics
/// The samples have different lengths.
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "two samples of the same cells");
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_linear_relation_correlates_fully_and_independent_samples_do_not() {
        let a = [1.0, 2.0, 3.0, 4.0];
        assert!((correlation(&a, &a.map(|x| 3.0 * x + 1.0)) - 1.0).abs() < 1e-12);
        assert!((correlation(&a, &a.map(|x| -x)) + 1.0).abs() < 1e-12);
        // Orthogonal deviations from the means: no correlation.
        assert!(correlation(&[1.0, -1.0, 1.0, -1.0], &[1.0, 1.0, -1.0, -1.0]).abs() < 1e-12);
        assert!(correlation(&a, &[2.0; 4]).is_nan());
    }
}
