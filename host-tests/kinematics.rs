use m2ctl::kinematics::*;
use m2ctl::nominal::PROTOTYPE;
use m2ctl::selftest;

#[test]
fn quick() {
    let g32 = Geometry::<f32>::new(&PROTOTYPE).unwrap();
    let s = selftest::run_all(&g32, |i, o| {
        println!(
            "{i} {:?}",
            (
                o.ik_err_mm * 1e6,
                o.fk_err_mm * 1e6,
                o.fk_err_arcsec,
                o.fk_iterations,
                o.pass
            )
        )
    });
    println!("{s:?}");
}

#[test]
fn sweep() {
    let g32 = Geometry::<f32>::new(&PROTOTYPE).unwrap();
    let g64 = Geometry::<f64>::new(&PROTOTYPE).unwrap();
    let mut st = 12345u64;
    let mut rnd = || {
        st ^= st << 13;
        st ^= st >> 7;
        st ^= st << 17;
        (st >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut worst = 0.0f64;
    let mut worst_fk = 0.0f64;
    let mut worst_as = 0.0f64;
    for n in 0..200000 {
        let corner = n % 4 == 0;
        let mut v = [0.0; 6];
        for k in 0..6 {
            let r = if corner { rnd().signum() } else { rnd() };
            v[k] = if k < 3 {
                2.0 * r
            } else {
                600.0 * r / ARCSEC_PER_RAD
            };
        }
        let p32 = Pose::<f32>::from_array(v.map(|x| x as f32));
        let p64: Pose<f64> = p32.cast();
        let s32 = ik(&g32, &p32).unwrap();
        let s64 = ik(&g64, &p64).unwrap();
        for i in 0..6 {
            worst = worst.max((s32[i] as f64 - s64[i]).abs());
        }
        if n % 50 == 0 {
            let sol = fk(&g32, &s32, &Pose::home(), &FkConfig::default()).unwrap();
            let a = sol.pose.to_array();
            for k in 0..3 {
                worst_fk = worst_fk.max((a[k] as f64 - v[k]).abs());
                worst_as = worst_as.max((a[k + 3] as f64 - v[k + 3]).abs() * ARCSEC_PER_RAD);
            }
        }
    }
    println!(
        "worst f32 vs f64 {} nm ; fk {} nm {} as",
        worst * 1e6,
        worst_fk * 1e6,
        worst_as
    );
}
