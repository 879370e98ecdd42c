//! The stepped validation ([`ValidationState`], [`Validation`]) against [`validate`] and
//! against the run-to-completion implementation it replaced (`super::reference`): the
//! same result, bit for bit (the same error variant and detail), on valid tables, on
//! tables provoking every refusal code 0x0410..=0x041C, on random perturbations and on
//! tables with arbitrary numbers; and the number of steps within its bound.

use proptest::prelude::*;

use super::reference;
use super::*;
use crate::table::layout::Provenance;

/// Steps `t` to completion: the result and the number of steps taken (the step that
/// returned the result included). Checks on the way: no result before the end, never
/// more than [`MAX_VALIDATION_STEPS`] steps, and the result again at every later step.
fn stepped(t: &Table, cfg: &ValidationConfig) -> (Result<(), ValidationError>, u32) {
    let mut v = ValidationState::new();
    let mut steps = 0u32;
    loop {
        assert_eq!(v.result(), None, "a result before the last step");
        steps += 1;
        if let Some(r) = v.step(t, cfg) {
            assert_eq!(v.result(), Some(r));
            assert_eq!(v.step(t, cfg), Some(r), "the result is not repeated");
            return (r, steps);
        }
        assert!(
            steps < MAX_VALIDATION_STEPS,
            "no result after {steps} steps"
        );
    }
}

/// Most steps a validation with `cfg` may take: [`validation_steps`] of its grid, or
/// the two steps that refuse a grid out of range.
fn step_bound(cfg: &ValidationConfig) -> u32 {
    let n = cfg.grid_points_per_axis;
    if (MIN_GRID_POINTS_PER_AXIS..=MAX_GRID_POINTS_PER_AXIS).contains(&n) {
        validation_steps(n)
    } else {
        CHECK_STEPS
    }
}

/// The reference's result; asserts that the stepped validation (both APIs) and
/// `validate` give exactly it, within the step bound (exactly the bound if accepted).
fn check(t: &Table, cfg: &ValidationConfig) -> Result<(), ValidationError> {
    let want = reference::validate(t, cfg);
    let (got, steps) = stepped(t, cfg);
    assert_eq!(got, want, "stepped validation differs from the reference");
    assert_eq!(
        validate(t, cfg),
        want,
        "validate() differs from the reference"
    );
    let mut borrowed = Validation::new(t, cfg);
    let mut borrowed_steps = 1u32;
    let r = loop {
        if let Some(r) = borrowed.step() {
            break r;
        }
        borrowed_steps += 1;
    };
    assert_eq!((r, borrowed_steps), (want, steps), "Validation differs");
    let bound = step_bound(cfg);
    assert!(steps <= bound, "{steps} steps, bound {bound}");
    assert!(steps <= MAX_VALIDATION_STEPS);
    if want.is_ok() {
        assert_eq!(steps, bound, "an accepted table takes every step");
    }
    want
}

fn flight() -> ValidationConfig {
    ValidationConfig::flight()
}

/// A "calibrated" table: nominal joints moved by a few tenths of a mm.
fn calibrated(shift_mm: f64) -> Table {
    let mut t = Table::nominal();
    t.provenance = Provenance {
        calibration_id: 7,
        tag: *b"CAL-2025-07-01 A",
    };
    for (i, leg) in t.legs.iter_mut().enumerate() {
        let s = shift_mm * (1.0 + i as f64 / 10.0);
        leg.a_mm[0] += s;
        leg.a_mm[2] -= 0.5 * s;
        leg.b_mm[1] -= s;
    }
    t.p0_mm[2] += 0.1;
    t
}

/// The number at field index `field` of [`field_index`] (the supervision thresholds
/// as `f32`).
fn set_field(t: &mut Table, field: u16, v: f64) {
    let f = usize::from(field);
    match field {
        0..36 => {
            let leg = &mut t.legs[f / 6];
            if f % 6 < 3 {
                leg.a_mm[f % 6] = v;
            } else {
                leg.b_mm[f % 6 - 3] = v;
            }
        }
        36..39 => t.p0_mm[f - 36] = v,
        39..45 => t.stroke_limits.min_mm[f - 39] = v,
        45..51 => t.stroke_limits.max_mm[f - 45] = v,
        51..54 => t.workspace.translation_mm[f - 51] = v,
        54..57 => t.workspace.rotation_rad[f - 54] = v,
        57 => t.supervision.following_error_warning_mm = v as f32,
        58 => t.supervision.following_error_fault_mm = v as f32,
        59 => t.supervision.encoder_jump_mm_per_cycle = v as f32,
        60 => t.supervision.stuck_min_progress_mm = v as f32,
        _ => assert!(field < FIELDS, "no field {field}"),
    }
}

/// The number at field index `field` (as [`set_field`]).
fn get_field(t: &Table, field: u16) -> f64 {
    let f = usize::from(field);
    match field {
        0..36 => t.joint_coord_mm(f).unwrap_or(f64::NAN),
        36..39 => t.p0_mm[f - 36],
        39..45 => t.stroke_limits.min_mm[f - 39],
        45..51 => t.stroke_limits.max_mm[f - 45],
        51..54 => t.workspace.translation_mm[f - 51],
        54..57 => t.workspace.rotation_rad[f - 54],
        57 => f64::from(t.supervision.following_error_warning_mm),
        58 => f64::from(t.supervision.following_error_fault_mm),
        59 => f64::from(t.supervision.encoder_jump_mm_per_cycle),
        60 => f64::from(t.supervision.stuck_min_progress_mm),
        _ => {
            assert!(field < FIELDS, "no field {field}");
            f64::NAN
        }
    }
}

/// Fields of [`field_index`]: 0..61.
const FIELDS: u16 = field_index::SUPERVISION + 4;

/// A table whose leg 2 is a copy of leg 1 moved by `eps` mm (rod length kept to well
/// under the tolerance), with a coordinate tolerance that lets it through: the legs are
/// nearly redundant, so FK from home at the corners is singular, ill-conditioned (it
/// converges, but not to the corner) or does not converge within its iterations.
fn twin_legs(eps: f64) -> (Table, ValidationConfig) {
    let mut t = Table::nominal();
    let l0 = t.legs[0];
    t.legs[1].a_mm = [l0.a_mm[0] + eps, l0.a_mm[1] - 0.7 * eps, l0.a_mm[2]];
    t.legs[1].b_mm = [l0.b_mm[0] + 0.3 * eps, l0.b_mm[1] + eps, l0.b_mm[2]];
    let cfg = ValidationConfig {
        max_coordinate_deviation_mm: 200.0,
        ..flight()
    };
    (t, cfg)
}

#[test]
fn accepted_tables_take_every_step() {
    for t in [Table::nominal(), calibrated(0.3), calibrated(-0.4)] {
        for n in MIN_GRID_POINTS_PER_AXIS..=MAX_GRID_POINTS_PER_AXIS {
            let cfg = ValidationConfig {
                grid_points_per_axis: n,
                ..flight()
            };
            assert_eq!(check(&t, &cfg), Ok(()), "n = {n}");
        }
    }
    assert_eq!(validation_steps(DEFAULT_GRID_POINTS_PER_AXIS), 99);
    assert_eq!(MAX_VALIDATION_STEPS, 720);
}

/// Every refusal code, each provoked (most of them in several ways), and the same
/// verdict every way.
#[test]
fn every_refusal_code() {
    let mut seen = [0u32; 13];
    let mut note = |r: Result<(), ValidationError>| {
        if let Err(e) = r {
            seen[usize::from(e.code() - 0x0410)] += 1;
        }
        r
    };
    let cal = calibrated(0.1);

    // 0x0410: every byte of the tag.
    for i in 0..cal.provenance.tag.len() {
        let mut t = cal;
        t.provenance.tag[i] = 0x80 + i as u8;
        let want = Err(ValidationError::ProvenanceNotAscii { index: i as u8 });
        assert_eq!(note(check(&t, &flight())), want);
    }
    // 0x0411: every field NaN, +inf, -inf (after a non-ASCII tag byte: that first).
    for field in 0..FIELDS {
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut t = cal;
            set_field(&mut t, field, v);
            assert_eq!(
                note(check(&t, &flight())),
                Err(ValidationError::NonFinite { field })
            );
            t.provenance.tag[0] = 1;
            assert_eq!(
                note(check(&t, &flight())),
                Err(ValidationError::ProvenanceNotAscii { index: 0 })
            );
        }
    }
    // 0x0412: every coordinate and p0 component 1.5 mm off, either way.
    for index in 0..field_index::STROKE_MIN {
        for d in [1.5, -1.5] {
            let mut t = cal;
            set_field(&mut t, index, get_field(&cal, index) + d);
            assert_eq!(
                note(check(&t, &flight())),
                Err(ValidationError::CoordinateOffNominal { index: index as u8 })
            );
        }
    }
    // 0x0413: rods 5 mm long with a loose coordinate tolerance, each leg.
    let loose = ValidationConfig {
        max_coordinate_deviation_mm: 10.0,
        ..flight()
    };
    for leg in 0..LEGS {
        let mut t = cal;
        t.legs[leg].b_mm[2] += 5.0;
        assert_eq!(
            note(check(&t, &loose)),
            Err(ValidationError::RodLengthImplausible { leg: leg as u8 })
        );
    }
    // 0x0414: stroke limits not containing home, a negative workspace half-range, a
    // rod that does not lean upwards (same length, nearly horizontal).
    for leg in 0..LEGS {
        let mut t = cal;
        t.stroke_limits.min_mm[leg] = 0.5;
        assert_eq!(
            note(check(&t, &flight())),
            Err(ValidationError::Geometry(GeometryError::BadStrokeLimits {
                leg: leg as u8
            }))
        );
    }
    let mut t = cal;
    t.workspace.rotation_rad[1] = -1e-6;
    assert_eq!(
        note(check(&t, &flight())),
        Err(ValidationError::Geometry(GeometryError::BadWorkspaceLimits))
    );
    let very_loose = ValidationConfig {
        max_coordinate_deviation_mm: 1000.0,
        ..flight()
    };
    let mut t = cal;
    let d0 = home_rod_mm(&t.legs[3], &t.p0_mm);
    let l = norm3(d0);
    let b = t.legs[3].b_mm;
    let p0 = t.p0_mm;
    t.legs[3].a_mm = [
        b[0] + p0[0] - libm::sqrt(l * l - 0.25),
        b[1] + p0[1],
        b[2] + p0[2] - 0.5,
    ];
    assert_eq!(
        note(check(&t, &very_loose)),
        Err(ValidationError::Geometry(
            GeometryError::UpperNotAboveLower { leg: 3 }
        ))
    );
    // 0x0415, 0x0416: beyond the caps, each leg and axis.
    let caps = flight();
    for leg in 0..LEGS {
        let mut t = cal;
        t.stroke_limits.max_mm[leg] = caps.max_abs_stroke_limit_mm * 1.001;
        assert_eq!(
            note(check(&t, &flight())),
            Err(ValidationError::StrokeLimitBeyondCap { leg: leg as u8 })
        );
        let mut t = cal;
        t.stroke_limits.min_mm[leg] = -caps.max_abs_stroke_limit_mm * 1.001;
        assert_eq!(
            note(check(&t, &flight())),
            Err(ValidationError::StrokeLimitBeyondCap { leg: leg as u8 })
        );
    }
    for axis in 0..6u16 {
        let mut t = cal;
        let f = field_index::WORKSPACE_TRANSLATION + axis;
        set_field(&mut t, f, get_field(&cal, f) * 1.001);
        assert_eq!(
            note(check(&t, &flight())),
            Err(ValidationError::WorkspaceBeyondCap { axis: axis as u8 })
        );
    }
    // 0x0417: each threshold not positive, warning >= fault, each count zero.
    for field in 0..4u16 {
        let mut t = cal;
        set_field(&mut t, field_index::SUPERVISION + field, 0.0);
        assert_eq!(
            note(check(&t, &flight())),
            Err(ValidationError::Supervision { field: field as u8 })
        );
    }
    let mut t = cal;
    t.supervision.following_error_warning_mm = t.supervision.following_error_fault_mm;
    assert_eq!(
        note(check(&t, &flight())),
        Err(ValidationError::Supervision { field: 1 })
    );
    for k in 0..3u8 {
        let mut t = cal;
        match k {
            0 => t.supervision.stuck_detection_cycles = 0,
            1 => t.supervision.warning_debounce_cycles = 0,
            _ => t.supervision.fault_debounce_cycles = 0,
        }
        assert_eq!(
            note(check(&t, &flight())),
            Err(ValidationError::Supervision { field: 4 + k })
        );
    }
    // 0x0418: a workspace so wide (caps opened) that a rod might turn horizontal.
    let wide = ValidationConfig {
        max_workspace: WorkspaceLimits {
            translation_mm: [100.0; 3],
            rotation_rad: [1.0; 3],
        },
        ..flight()
    };
    let mut t = cal;
    t.workspace.rotation_rad = t.workspace.rotation_rad.map(|r| 50.0 * r);
    assert_eq!(
        note(check(&t, &wide)),
        Err(ValidationError::Unreachable { legs: 0x3f })
    );
    // 0x0419: limits tighter than the corners need; one leg's only.
    let mut t = cal;
    t.stroke_limits.min_mm = [-3.0; 6];
    t.stroke_limits.max_mm = [3.0; 6];
    assert!(matches!(
        note(check(&t, &flight())),
        Err(ValidationError::StrokeLimitExceeded { legs }) if legs != 0
    ));
    let mut t = cal;
    t.stroke_limits.max_mm[4] = 1.0;
    assert_eq!(
        note(check(&t, &flight())),
        Err(ValidationError::StrokeLimitExceeded { legs: 1 << 4 })
    );
    // 0x041A, 0x041B: nearly redundant legs (FK singular, not converging, or
    // converging away from the corner), at several corners.
    let mut fk_codes = [0u32; 6];
    let mut corners = 0u64;
    for k in 0..40 {
        let (t, cfg) = twin_legs(0.001 * 1.2f64.powi(k));
        match note(check(&t, &cfg)) {
            Err(ValidationError::FkFailed { corner, fk_code }) => {
                corners |= 1 << corner;
                fk_codes[usize::from(fk_code & 0xf)] += 1;
            }
            Err(ValidationError::FkInaccurate { corner }) => corners |= 1 << corner,
            _ => {}
        }
    }
    // Singular Jacobian (0x0303) and no convergence within the iterations (0x0304).
    assert!(fk_codes[3] > 0 && fk_codes[4] > 0, "FK codes {fk_codes:?}");
    assert!(corners.count_ones() >= 3, "corners {corners:#x}");
    // 0x041C: grids out of range (after the checks before them).
    for n in [0, 1, MAX_GRID_POINTS_PER_AXIS + 1, u8::MAX] {
        let cfg = ValidationConfig {
            grid_points_per_axis: n,
            ..flight()
        };
        assert_eq!(note(check(&cal, &cfg)), Err(ValidationError::BadConfig));
        let mut t = cal;
        t.supervision.fault_debounce_cycles = 0;
        assert_eq!(
            note(check(&t, &cfg)),
            Err(ValidationError::Supervision { field: 6 })
        );
    }
    for (k, n) in seen.iter().enumerate() {
        assert!(*n > 0, "code {:#06x} never provoked", 0x0410 + k);
    }
}

/// The twin-leg table of the self-test image's longest corner step (m2selftest,
/// `TWIN_LEG_OFFSET_MM`): FK from home at corner 1 runs to its iteration limit.
#[test]
fn twin_legs_of_the_self_test() {
    let (t, cfg) = twin_legs(0.1);
    let r = check(&t, &cfg);
    assert_eq!(
        r,
        Err(ValidationError::FkFailed {
            corner: 1,
            fk_code: crate::kinematics::FkError::NotConverged {
                iterations: crate::kinematics::fk::FK_MAX_ITERATIONS
            }
            .code()
        })
    );
    assert_eq!(r.map_err(|e| (e.code(), e.detail())), Err((0x041a, 0x0401)));
    assert_eq!(stepped(&t, &cfg).1, CHECK_STEPS + MARGIN_STEPS + 31 + 2);
}

/// A validation's state copied after any step and stepped on from there gives the same
/// result in the same number of steps: the state is all there is.
#[test]
fn resumes_from_any_copy() {
    for (t, cfg) in [
        (Table::nominal(), flight()),
        (calibrated(0.2), flight()),
        twin_legs(0.1),
    ] {
        let (want, steps) = stepped(&t, &cfg);
        let mut v = ValidationState::new();
        for k in 1..=steps {
            let mut copy = v;
            let mut more = 0;
            let r = loop {
                more += 1;
                if let Some(r) = copy.step(&t, &cfg) {
                    break r;
                }
            };
            assert_eq!((r, k - 1 + more), (want, steps));
            let _ = v.step(&t, &cfg);
        }
        assert_eq!(v.result(), Some(want));
    }
}

/// A change [`perturbed`] makes to a table that is otherwise near the flight one.
#[derive(Clone, Copy, Debug)]
enum Fault {
    /// None: the table may pass (or fail on its limits or workspace).
    None,
    /// A number set to NaN or an infinity (field index, value).
    NonFinite(u16, f64),
    /// A coordinate or p0 component moved by this much more (field index, mm).
    Off(u16, f64),
    /// A tag byte set (index, byte).
    Tag(usize, u8),
    /// A leg's upper stroke limit set (leg, mm).
    Limit(usize, f64),
    /// A workspace half-range scaled (axis, factor of its cap).
    Workspace(u16, f64),
    /// The warning and fault thresholds set (mm).
    Thresholds(f32, f32),
}

/// A state past the geometry step without the geometry (cannot happen: a defect or a
/// RAM upset) starts over at the checks, and still gives the reference's result.
#[test]
fn a_stage_without_its_geometry_starts_over() {
    for (t, cfg) in [(calibrated(0.2), flight()), twin_legs(0.1)] {
        let want = reference::validate(&t, &cfg);
        for stage in [Stage::Grid, Stage::Corners] {
            let mut v = ValidationState::new();
            v.stage = stage;
            v.next = 5;
            v.unreachable = 1;
            v.beyond = 2;
            assert_eq!(v.step(&t, &cfg), None);
            assert_eq!(
                (v.stage, v.next, v.unreachable, v.beyond),
                (Stage::Checks, 0, 0, 0)
            );
            let mut steps = 1;
            let r = loop {
                steps += 1;
                if let Some(r) = v.step(&t, &cfg) {
                    break r;
                }
            };
            assert_eq!(r, want);
            assert_eq!(steps, 1 + stepped(&t, &cfg).1);
        }
    }
}

/// Strategy: a table near the flight one (every coordinate moved within the tolerance,
/// limits and workspace that may or may not leave room) with at most one [`Fault`],
/// and a grid density, mostly in range.
fn perturbed() -> impl Strategy<Value = (Table, ValidationConfig)> {
    let fault = prop_oneof![
        8 => Just(Fault::None),
        1 => (0..FIELDS, prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(-f64::INFINITY)])
            .prop_map(|(f, v)| Fault::NonFinite(f, v)),
        1 => (0..field_index::STROKE_MIN, -1.0f64..1.0).prop_map(|(f, d)| Fault::Off(f, d)),
        1 => (0usize..16, 0x7fu8..=0xff).prop_map(|(i, b)| Fault::Tag(i, b)),
        2 => (0..LEGS, -0.5f64..5.0).prop_map(|(l, v)| Fault::Limit(l, v)),
        1 => (0u16..6, 0.9f64..1.1).prop_map(|(k, f)| Fault::Workspace(k, f)),
        1 => (0.0f32..2.0, 0.0f32..2.0).prop_map(|(w, f)| Fault::Thresholds(w, f)),
    ];
    (
        proptest::collection::vec(-0.45f64..0.45, 39),
        (3.6f64..5.0, 3.6f64..5.0),
        proptest::collection::vec(0.0f64..1.0, 6),
        fault,
        prop_oneof![
            10 => Just(DEFAULT_GRID_POINTS_PER_AXIS),
            4 => Just(2u8),
            1 => Just(4u8),
            1 => Just(5u8),
            1 => 0u8..=8,
        ],
    )
        .prop_map(|(d, (lo, hi), ws, fault, points)| {
            let mut t = calibrated(0.0);
            for (field, dv) in d.iter().enumerate() {
                let f = field as u16;
                let v = get_field(&t, f) + dv;
                set_field(&mut t, f, v);
            }
            t.stroke_limits.min_mm = [-lo; 6];
            t.stroke_limits.max_mm = [hi; 6];
            let caps = flight().max_workspace;
            let cap = |k: u16| {
                let k = usize::from(k);
                if k < 3 {
                    caps.translation_mm[k]
                } else {
                    caps.rotation_rad[k - 3]
                }
            };
            for (k, s) in ws.iter().enumerate() {
                let k = k as u16;
                set_field(&mut t, field_index::WORKSPACE_TRANSLATION + k, s * cap(k));
            }
            match fault {
                Fault::None => {}
                Fault::NonFinite(f, v) => set_field(&mut t, f, v),
                Fault::Off(f, d) => {
                    let v = get_field(&t, f) + d.signum() * 0.6 + d;
                    set_field(&mut t, f, v);
                }
                Fault::Tag(i, b) => t.provenance.tag[i] = b,
                Fault::Limit(leg, v) => t.stroke_limits.max_mm[leg] = v,
                Fault::Workspace(k, f) => {
                    set_field(&mut t, field_index::WORKSPACE_TRANSLATION + k, f * cap(k))
                }
                Fault::Thresholds(w, f) => {
                    t.supervision.following_error_warning_mm = w;
                    t.supervision.following_error_fault_mm = f;
                }
            }
            let cfg = ValidationConfig {
                grid_points_per_axis: points,
                ..flight()
            };
            (t, cfg)
        })
}

/// Strategy: the flight table with up to six numbers replaced by arbitrary ones (any
/// bit pattern: NaN, infinities, subnormals, huge), under a configuration with opened
/// tolerances and caps now and then, so that later checks are reached too.
fn arbitrary_numbers() -> impl Strategy<Value = (Table, ValidationConfig)> {
    (
        proptest::collection::vec((0..FIELDS, any::<f64>()), 1..6),
        any::<bool>(),
        2u8..=3,
    )
        .prop_map(|(changes, open, points)| {
            let mut t = Table::nominal();
            for (field, v) in changes {
                set_field(&mut t, field, v);
            }
            let mut cfg = ValidationConfig {
                grid_points_per_axis: points,
                ..flight()
            };
            if open {
                cfg.max_coordinate_deviation_mm = 1e300;
                cfg.max_rod_deviation_mm = 1e300;
                cfg.max_abs_stroke_limit_mm = 1e300;
                cfg.max_workspace = WorkspaceLimits {
                    translation_mm: [1e300; 3],
                    rotation_rad: [1e300; 3],
                };
            }
            (t, cfg)
        })
}

/// Cases of each property test.
const CASES: u32 = 400;

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, failure_persistence: None, ..ProptestConfig::default() })]

    /// Random perturbations: the same result all three ways, steps within the bound.
    #[test]
    fn perturbed_tables_agree((t, cfg) in perturbed()) {
        let _ = check(&t, &cfg);
    }

    /// Arbitrary numbers: the same result all three ways, steps within the bound.
    #[test]
    fn arbitrary_numbers_agree((t, cfg) in arbitrary_numbers()) {
        let _ = check(&t, &cfg);
    }

    /// Twin legs of any offset (the FK refusals and what lies around them).
    #[test]
    fn twin_legs_agree(eps in 0.0f64..1.5, points in 2u8..=3) {
        let (t, mut cfg) = twin_legs(eps);
        cfg.grid_points_per_axis = points;
        let _ = check(&t, &cfg);
    }
}

/// What the random strategies cover (deterministic runs of their first [`CASES`]
/// values): acceptance and most refusal codes, so the property tests compare more than
/// one outcome.
#[test]
fn strategies_cover_the_outcomes() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut outcomes = std::collections::BTreeMap::<u16, u32>::new();
    let mut runner = TestRunner::deterministic();
    for _ in 0..CASES {
        for (t, cfg) in [
            perturbed().new_tree(&mut runner).map(|v| v.current()),
            arbitrary_numbers()
                .new_tree(&mut runner)
                .map(|v| v.current()),
        ]
        .into_iter()
        .flatten()
        {
            let code = validate(&t, &cfg).err().map_or(0, |e| e.code());
            *outcomes.entry(code).or_default() += 1;
        }
    }
    std::println!("outcomes (code: tables): {outcomes:x?}");
    assert!(
        outcomes.get(&0).copied().unwrap_or(0) >= CASES / 20,
        "{outcomes:x?}"
    );
    assert!(outcomes.len() >= 11, "{outcomes:x?}");
}
