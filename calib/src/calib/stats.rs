//! The chi-square distribution for the adjustment's tests: central CDF and quantile
//! (global test, confidence intervals, critical values of the outlier tests) and the
//! non-central CDF (power of a test: Baarda's minimal detectable bias). Regularised
//! incomplete gamma function by its series and continued fraction (Numerical Recipes
//! 6.2), log-gamma by Lanczos (g = 7, 9 terms), the one Lanczos series also giving the
//! Gamma function of the cuckoo search's Levy steps; quantiles by bisection.

/// Lanczos approximation (g = 7, n = 9) of the Gamma function, relative error ~1e-15.
const LANCZOS_G: f64 = 7.0;
/// Its coefficients.
const LANCZOS: [f64; 9] = [
    0.999_999_999_999_809_9,
    676.520_368_121_885_1,
    -1_259.139_216_722_402_8,
    771.323_428_777_653_1,
    -176.615_029_162_140_6,
    12.507_343_278_686_905,
    -0.138_571_095_265_720_12,
    9.984_369_578_019_572e-6,
    1.505_632_735_149_311_6e-7,
];

/// The Lanczos series at `x = z - 1` (z >= 0.5): `(t, A)` with `t = x + g + 1/2` and
/// `Gamma(z) = sqrt(2 pi) t^(x + 1/2) e^-t A`.
fn lanczos(x: f64) -> (f64, f64) {
    let mut a = LANCZOS[0];
    let t = x + LANCZOS_G + 0.5;
    for (i, c) in LANCZOS.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    (t, a)
}

/// `ln Gamma(x)`, x > 0 (Lanczos, relative error ~1e-15).
pub fn ln_gamma(x: f64) -> f64 {
    if x < 0.5 {
        // Reflection.
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let (t, a) = lanczos(x);
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The Gamma function (Lanczos approximation, ~1e-15 relative for the arguments here;
/// reflection below 0.5).
pub fn gamma(x: f64) -> f64 {
    use std::f64::consts::PI;
    if x < 0.5 {
        PI / ((PI * x).sin() * gamma(1.0 - x))
    } else {
        let x = x - 1.0;
        let (t, a) = lanczos(x);
        (2.0 * PI).sqrt() * t.powf(x + 0.5) * (-t).exp() * a
    }
}

/// Regularised lower incomplete gamma `P(a, x)`.
pub fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if !x.is_finite() {
        return 1.0;
    }
    let lead = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        // Series.
        let mut ap = a;
        let mut sum = 1.0 / a;
        let mut del = sum;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (sum.ln() + lead).exp().min(1.0)
    } else {
        (1.0 - gamma_q_continued_fraction(a, x)).max(0.0)
    }
}

/// Regularised upper incomplete gamma `Q(a, x)` by its continued fraction (Lentz), for
/// `x >= a + 1` where it converges fast and, unlike `1 - P`, keeps its precision far into
/// the tail.
fn gamma_q_continued_fraction(a: f64, x: f64) -> f64 {
    let lead = -x + a * x.ln() - ln_gamma(a);
    let tiny = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / tiny;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..10_000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < tiny {
            d = tiny;
        }
        c = b + an / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-16 {
            break;
        }
    }
    lead.exp() * h
}

/// CDF of the chi-square distribution with `dof` degrees of freedom.
pub fn chi2_cdf(x: f64, dof: f64) -> f64 {
    gamma_p(0.5 * dof, 0.5 * x)
}

/// Upper tail `P(X > x)` of the chi-square distribution (accurate far into the tail).
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    let a = 0.5 * dof;
    let h = 0.5 * x;
    if h < a + 1.0 {
        1.0 - gamma_p(a, h)
    } else {
        // Q directly from the continued fraction (no cancellation).
        gamma_q_continued_fraction(a, h)
    }
}

/// The `p` quantile of the chi-square distribution (`P(X <= x) = p`), `0 < p < 1`.
pub fn chi2_quantile(p: f64, dof: f64) -> f64 {
    // Upper-tail form for small tails: solve sf(x) = 1 - p without cancellation.
    let q = 1.0 - p;
    let f = |x: f64| {
        if q < 0.5 {
            chi2_sf(x, dof) - q
        } else {
            p - chi2_cdf(x, dof)
        }
    };
    // f decreases in x (sf falls; p - cdf falls).
    let (mut lo, mut hi) = (0.0, dof.max(1.0));
    while f(hi) > 0.0 {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Upper tail of the non-central chi-square distribution, `P(X > x)` for `dof` degrees
/// of freedom and non-centrality `lambda` (Poisson mixture of central ones).
pub fn noncentral_chi2_sf(x: f64, dof: f64, lambda: f64) -> f64 {
    let h = 0.5 * lambda;
    // Sum over j of Poisson(j; h) * sf(x; dof + 2 j), from the mode both ways.
    let mode = h.floor() as i64;
    let weight = |j: i64| (-h + j as f64 * h.max(1e-300).ln() - ln_gamma(j as f64 + 1.0)).exp();
    let mut total = 0.0;
    let mut j = mode;
    loop {
        let w = if h == 0.0 && j == 0 { 1.0 } else { weight(j) };
        total += w * chi2_sf(x, dof + 2.0 * j as f64);
        if (w < 1e-17 && j > mode) || j > mode + 100_000 {
            break;
        }
        j += 1;
    }
    let mut j = mode - 1;
    while j >= 0 {
        let w = weight(j);
        total += w * chi2_sf(x, dof + 2.0 * j as f64);
        if w < 1e-17 {
            break;
        }
        j -= 1;
    }
    total.min(1.0)
}

/// The non-centrality at which a chi-square test with `dof` degrees of freedom and
/// critical value `critical` rejects with probability `power` (Baarda's lambda_0).
pub fn noncentrality_for_power(critical: f64, dof: f64, power: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    while noncentral_chi2_sf(critical, dof, hi) < power {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if noncentral_chi2_sf(critical, dof, mid) < power {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-9 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_quantiles_match_the_tables() {
        // Abramowitz & Stegun table 26.8 / any chi-square table.
        for (p, k, x) in [
            (0.95, 1.0, 3.841_459),
            (0.999, 1.0, 10.827_566),
            (0.95, 3.0, 7.814_728),
            (0.99, 3.0, 11.344_867),
            (0.025, 10.0, 3.246_973),
            (0.975, 10.0, 20.483_177),
            (0.5, 100.0, 99.334_129),
            (0.975, 1000.0, 1_089.531_0),
        ] {
            let q = chi2_quantile(p, k);
            assert!((q - x).abs() < 1e-5 * x, "p {p} dof {k}: {q} vs {x}");
            assert!((chi2_cdf(x, k) - p).abs() < 1e-6);
        }
        // Far tail: 1-D, 1e-9 two-sided is |z| > 6.1094.
        let q = chi2_quantile(1.0 - 1e-9, 1.0);
        assert!((q.sqrt() - 6.109_410_2).abs() < 1e-5, "{}", q.sqrt());
    }

    #[test]
    fn baarda_lambda0_of_the_b_method() {
        // Baarda's B-method: alpha0 = 0.001, power 0.80, 1-D: lambda0 = 17.07.
        let c = chi2_quantile(0.999, 1.0);
        let l = noncentrality_for_power(c, 1.0, 0.8);
        assert!((l - 17.07).abs() < 0.02, "{l}");
        // A non-central chi-square with lambda = 0 is the central one.
        assert!((noncentral_chi2_sf(7.0, 3.0, 0.0) - chi2_sf(7.0, 3.0)).abs() < 1e-12);
    }
}
