//! The statistics of the sweep report: the Wilson score interval of a pass rate and
//! Fisher's exact test of two pass counts (is the new pilot worse than the old one?).
//!
//! Pure functions of counts; no sampling, no state: the same counts give the same bits.

/// The standard normal quantile `z` with `P(Z <= z) = p`, for `0 < p < 1`: Wichura's
/// algorithm AS241 (PPND16, Applied Statistics 37(3), 1988), rational approximations in
/// three regions of `p` with a relative error below 1e-16. `p` outside (0, 1) gives
/// minus or plus infinity (0 and below, 1 and above).
// The coefficients as published, digit for digit, so they can be checked against AS241.
#[allow(clippy::excessive_precision)]
pub fn normal_quantile(p: f64) -> f64 {
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    let q = p - 0.5;
    if q.abs() <= 0.425 {
        // Central region: z = q * A(r) / B(r) with r = 0.425² - q².
        let r = 0.180625 - q * q;
        let a = [
            3.387_132_872_796_366_608,
            133.141_667_891_784_377_45,
            1_971.590_950_306_551_442_7,
            13_731.693_765_509_461_125,
            45_921.953_931_549_871_457,
            67_265.770_927_008_700_853,
            33_430.575_583_588_128_105,
            2_509.080_928_730_122_672_7,
        ];
        let b = [
            1.0,
            42.313_330_701_600_911_252,
            687.187_007_492_057_908_3,
            5_394.196_021_424_751_107_7,
            21_213.794_301_586_595_867,
            39_307.895_800_092_710_61,
            28_729.085_735_721_942_674,
            5_226.495_278_852_854_561,
        ];
        return q * poly(&a, r) / poly(&b, r);
    }
    // Tails: r = sqrt(-ln(min(p, 1 - p))), z = ±C(r - 1.6)/D(r - 1.6) up to r = 5
    // (p down to about 1.4e-11), ±E(r - 5)/F(r - 5) beyond.
    let tail = if q < 0.0 { p } else { 1.0 - p };
    let r = (-tail.ln()).sqrt();
    let z = if r <= 5.0 {
        let c = [
            1.423_437_110_749_683_577_34,
            4.630_337_846_156_545_295_9,
            5.769_497_221_460_691_405_5,
            3.647_848_324_763_204_605_04,
            1.270_458_252_452_368_382_58,
            0.241_780_725_177_450_611_77,
            0.022_723_844_989_269_184_583_3,
            7.745_450_142_783_414_076_4e-4,
        ];
        let d = [
            1.0,
            2.053_191_626_637_758_821_87,
            1.676_384_830_183_803_849_4,
            0.689_767_334_985_100_004_55,
            0.148_103_976_427_480_074_59,
            0.015_198_666_563_616_457_196_6,
            5.475_938_084_995_344_946e-4,
            1.050_750_071_644_416_843_24e-9,
        ];
        poly(&c, r - 1.6) / poly(&d, r - 1.6)
    } else {
        let e = [
            6.657_904_643_501_103_777_2,
            5.463_784_911_164_114_369_9,
            1.784_826_539_917_291_335_8,
            0.296_560_571_828_504_891_23,
            0.026_532_189_526_576_123_093,
            0.001_242_660_947_388_078_438_6,
            2.711_555_568_743_487_578_15e-5,
            2.010_334_399_292_288_132_65e-7,
        ];
        let f = [
            1.0,
            0.599_832_206_555_887_937_69,
            0.136_929_880_922_735_805_31,
            0.014_875_361_290_850_614_852_5,
            7.868_691_311_456_132_591e-4,
            1.846_318_317_510_054_681_8e-5,
            1.421_511_758_316_445_888_7e-7,
            2.044_263_103_389_939_785_64e-15,
        ];
        poly(&e, r - 5.0) / poly(&f, r - 5.0)
    };
    if q < 0.0 { -z } else { z }
}

/// `coefficients[0] + coefficients[1] x + ...` by Horner's rule.
fn poly(coefficients: &[f64], x: f64) -> f64 {
    coefficients.iter().rev().fold(0.0, |acc, c| acc * x + c)
}

/// The Wilson score interval `(low, high)` of a pass rate: `successes` out of `n` runs,
/// two-sided at `confidence` (0.95: z = 1.96). With p̂ = s/n:
///
/// ```text
/// centre = (p̂ + z²/2n) / (1 + z²/n)
/// half   = z / (1 + z²/n) · sqrt(p̂(1 − p̂)/n + z²/4n²)
/// ```
///
/// Unlike p̂ ± z·sqrt(p̂(1 − p̂)/n) it stays inside [0, 1] and is not empty at 0/n or n/n,
/// the usual results of a sweep's cells. `n = 0` gives (0, 1): nothing is known.
///
/// # Assumptions
/// `successes <= n` (more is clamped to `n`), `0 < confidence < 1`.
pub fn wilson(successes: u32, n: u32, confidence: f64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let n_f = f64::from(n);
    let p = f64::from(successes.min(n)) / n_f;
    let z = normal_quantile(0.5 + confidence / 2.0);
    let z2 = z * z;
    let denominator = 1.0 + z2 / n_f;
    let centre = (p + z2 / (2.0 * n_f)) / denominator;
    let half = z / denominator * (p * (1.0 - p) / n_f + z2 / (4.0 * n_f * n_f)).sqrt();
    // At 0/n and n/n the bounds are exactly 0 and 1 (centre ∓ half cancel but for rounding).
    let low = if successes == 0 { 0.0 } else { (centre - half).max(0.0) };
    let high = if successes >= n { 1.0 } else { (centre + half).min(1.0) };
    (low, high)
}

/// The 2x2 table of Fisher's test: passes of the old and the new runs, with the
/// probability of each possible count of new passes given the table's margins.
struct Table {
    /// Number of new passes, as observed.
    observed: u32,
    /// Lowest and highest possible number of new passes given the margins.
    low: u32,
    high: u32,
    /// log(k!) for k = 0..=all runs.
    log_factorial: Vec<f64>,
    old_n: u32,
    new_n: u32,
    passes: u32,
}

impl Table {
    fn new(old_pass: u32, old_n: u32, new_pass: u32, new_n: u32) -> Self {
        let old_pass = old_pass.min(old_n);
        let new_pass = new_pass.min(new_n);
        let total = old_n + new_n;
        let passes = old_pass + new_pass;
        // log k! as a running sum of logs: exact to rounding, and the table is built
        // once per test.
        let mut log_factorial = Vec::with_capacity(total as usize + 1);
        let mut sum = 0.0;
        log_factorial.push(0.0);
        for k in 1..=total {
            sum += f64::from(k).ln();
            log_factorial.push(sum);
        }
        let low = passes.saturating_sub(old_n);
        let high = passes.min(new_n);
        Self { observed: new_pass, low, high, log_factorial, old_n, new_n, passes }
    }

    /// log C(n, k).
    fn log_choose(&self, n: u32, k: u32) -> f64 {
        let f = &self.log_factorial;
        f[n as usize] - f[k as usize] - f[(n - k) as usize]
    }

    /// P(X = x) for the hypergeometric X, the number of new passes when `passes` passes
    /// fall at random among `old_n + new_n` runs: C(new_n, x) C(old_n, passes − x) /
    /// C(old_n + new_n, passes).
    fn probability(&self, x: u32) -> f64 {
        let log_p = self.log_choose(self.new_n, x) + self.log_choose(self.old_n, self.passes - x)
            - self.log_choose(self.old_n + self.new_n, self.passes);
        log_p.exp()
    }
}

/// One-sided Fisher's exact test that the new runs pass less often than the old ones:
/// the probability, given the table's margins (the runs of each side and the passes of
/// both), that the new runs pass `new_pass` times or fewer. Small (below alpha): the new
/// runs' fewer passes are unlikely to be chance.
///
/// A side with no runs gives 1: nothing to compare.
pub fn fisher_one_sided_worse(old_pass: u32, old_n: u32, new_pass: u32, new_n: u32) -> f64 {
    let t = Table::new(old_pass, old_n, new_pass, new_n);
    let p: f64 = (t.low..=t.observed).map(|x| t.probability(x)).sum();
    p.min(1.0)
}

/// Two-sided Fisher's exact test of the same table: the probability of every table with
/// the same margins that is at most as likely as the observed one (with a relative
/// tolerance of 1e-7 for ties, as R's `fisher.test` and SciPy's `fisher_exact`).
pub fn fisher_two_sided(old_pass: u32, old_n: u32, new_pass: u32, new_n: u32) -> f64 {
    let t = Table::new(old_pass, old_n, new_pass, new_n);
    let observed = t.probability(t.observed);
    let p: f64 = (t.low..=t.high).map(|x| t.probability(x)).filter(|&p| p <= observed * (1.0 + 1e-7)).sum();
    p.min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tolerance: f64) -> bool {
        (a - b).abs() <= tolerance
    }

    #[test]
    fn normal_quantiles_match_scipy() {
        // scipy.stats.norm.ppf of each p (SciPy 1.x, computed for this test).
        let cases = [
            (0.975, 1.959_963_984_540_054),
            (0.995, 2.575_829_303_548_900_4),
            (0.9, 1.281_551_565_544_600_4),
            (0.5, 0.0),
            (0.025, -1.959_963_984_540_054),
            (1e-10, -6.361_340_902_404_056),
            (1e-20, -9.262_340_089_798_409),
        ];
        for (p, z) in cases {
            assert!(close(normal_quantile(p), z, 1e-9), "p {p}: {} vs {z}", normal_quantile(p));
        }
    }

    #[test]
    fn wilson_matches_known_intervals() {
        // 8/10 at 95 %: the textbook example (Newcombe 1998; statsmodels
        // proportion_confint(8, 10, method="wilson")).
        let (lo, hi) = wilson(8, 10, 0.95);
        assert!(close(lo, 0.490_162, 1e-5) && close(hi, 0.943_318, 1e-5), "({lo}, {hi})");
        // statsmodels proportion_confint(0, 10, alpha=0.05, method="wilson") = (0, 0.27753).
        let (lo, hi) = wilson(0, 10, 0.95);
        assert!(close(lo, 0.0, 1e-12) && close(hi, 0.277_532, 1e-5), "({lo}, {hi})");
        // 45/50 at 99 %: the formula evaluated in Python with z = scipy.stats.norm.ppf(0.995).
        let (lo, hi) = wilson(45, 50, 0.99);
        assert!(close(lo, 0.740_269_210_404_315_9, 1e-9) && close(hi, 0.966_009_116_221_581_7, 1e-9), "({lo}, {hi})");
        assert_eq!(wilson(0, 0, 0.95), (0.0, 1.0));
    }

    #[test]
    fn wilson_contains_the_rate_and_narrows_with_more_runs() {
        for n in 1..60 {
            for s in 0..=n {
                let (lo, hi) = wilson(s, n, 0.95);
                let p = f64::from(s) / f64::from(n);
                assert!((0.0..=p).contains(&lo) && (p..=1.0).contains(&hi), "{s}/{n}: ({lo}, {hi})");
                let (lo4, hi4) = wilson(4 * s, 4 * n, 0.95);
                assert!(hi4 - lo4 < hi - lo, "{s}/{n}: four times the runs narrows the interval");
                let (lo99, hi99) = wilson(s, n, 0.99);
                assert!(lo99 <= lo && hi99 >= hi, "{s}/{n}: more confidence widens it");
            }
        }
    }

    #[test]
    fn fisher_matches_the_tea_tasting_table_and_scipy() {
        // Fisher's lady tasting tea, [[3, 1], [1, 3]]: P = 17/70 one-sided, 34/70 two-sided.
        assert!(close(fisher_one_sided_worse(3, 4, 1, 4), 17.0 / 70.0, 1e-12));
        assert!(close(fisher_two_sided(3, 4, 1, 4), 34.0 / 70.0, 1e-12));
        // scipy.stats.fisher_exact([[old_pass, old_fail], [new_pass, new_fail]]) (SciPy 1.x,
        // computed for this test); alternative="greater" is the one-sided p that the new
        // side passes less.
        let cases = [
            // (old_pass, old_n, new_pass, new_n, one-sided, two-sided)
            (10, 10, 2, 10, 3.572_279_114_074_78e-4, 7.144_558_228_149_558e-4),
            (5, 10, 5, 10, 0.671_859_100_651_670_3, 1.0),
            (48, 50, 40, 50, 0.013_873_129_574_085_178, 0.027_746_259_148_170_36),
            (7, 12, 9, 12, 0.903_486_337_326_692_7, 0.666_846_143_491_721_8),
        ];
        for (op, on, np, nn, one, two) in cases {
            let (p1, p2) = (fisher_one_sided_worse(op, on, np, nn), fisher_two_sided(op, on, np, nn));
            assert!(close(p1, one, 1e-9), "{op}/{on} -> {np}/{nn}: one-sided {p1} vs {one}");
            assert!(close(p2, two, 1e-9), "{op}/{on} -> {np}/{nn}: two-sided {p2} vs {two}");
        }
    }

    #[test]
    fn fisher_p_values_are_probabilities_and_fall_as_the_new_side_fails_more() {
        let mut last = f64::INFINITY;
        for new_pass in (0..=20).rev() {
            let p = fisher_one_sided_worse(18, 20, new_pass, 20);
            assert!((0.0..=1.0).contains(&p), "{p}");
            assert!(p <= last, "fewer passes, smaller p");
            last = p;
            assert!((0.0..=1.0).contains(&fisher_two_sided(18, 20, new_pass, 20)));
        }
        assert_eq!(fisher_one_sided_worse(0, 0, 3, 5), 1.0, "no old runs: nothing to compare");
    }
}
