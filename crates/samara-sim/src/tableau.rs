//! Butcher tableaus of the explicit Runge-Kutta pairs, as data for the one adaptive driver
//! in [`crate::explicit_rk`].

use crate::dop853_tableau as d8;

/// Most stages of a tableau here (DOP853 has 12).
pub const MAX_STAGES: usize = 12;

/// How a pair estimates its local error from the stage derivatives `k_j`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ErrorEstimator {
    /// One embedded solution: the error is `h * sum_j e_j k_j`.
    Embedded([f64; MAX_STAGES]),
    /// DOP853's two estimators of orders 5 and 3 (`sum_j e5_j k_j`, `sum_j e3_j k_j`),
    /// combined as Hairer, Norsett & Wanner, *Solving ODEs I*, II.10.
    FifthAndThird {
        /// 5th-order error weights.
        e5: [f64; MAX_STAGES],
        /// 3rd-order error weights.
        e3: [f64; MAX_STAGES],
    },
}

/// An explicit Runge-Kutta pair for an autonomous system `y' = f(y)` (the nodes `c_i`
/// are not needed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tableau {
    /// Name, e.g. `DOP853`.
    pub name: &'static str,
    /// Number of stages `s`, including the FSAL stage when [`Tableau::fsal`].
    pub stages: usize,
    /// Stage matrix: stage `i` is `f(y + h * sum_{j<i} a[i][j] k_j)`.
    pub a: [[f64; MAX_STAGES]; MAX_STAGES],
    /// Weights of the propagated solution `y + h * sum_j b_j k_j` (over the first
    /// `stages - 1` stages when [`Tableau::fsal`], over all of them otherwise).
    pub b: [f64; MAX_STAGES],
    /// First same as last: the last stage is evaluated at the new solution (its row of
    /// `a` equals `b`), so it is the next step's first stage.
    pub fsal: bool,
    /// The local error estimate.
    pub error: ErrorEstimator,
    /// Exponent of the step-size update, `1 / (q + 1)` for error order `q`.
    pub exponent: f64,
    /// Continuous extension, if the pair has one: `y(t + s h) = y + h sum_j k_j
    /// (sum_p bi[j][p] s^(p+1))`, rows by stage (MATLAB's `ntrp45` for DP5(4)).
    pub interpolant: Option<[[f64; 4]; 7]>,
}

const fn row<const N: usize>(v: [f64; N]) -> [f64; MAX_STAGES] {
    let mut r = [0.0; MAX_STAGES];
    let mut i = 0;
    while i < N {
        r[i] = v[i];
        i += 1;
    }
    r
}

/// The 5th-order weights of DP5(4), also the row of its FSAL stage.
const DP54_B: [f64; 6] = [
    35.0 / 384.0,
    0.0,
    500.0 / 1113.0,
    125.0 / 192.0,
    -2187.0 / 6784.0,
    11.0 / 84.0,
];

/// Dormand-Prince 5(4) (Dormand & Prince 1980; the pair of MATLAB's `ode45`): seven
/// stages with FSAL, error weights "5th minus 4th order", and the `ntrp45` interpolant of
/// Shampine & Reichelt (1997).
pub const DP54: Tableau = Tableau {
    name: "DP5(4)",
    stages: 7,
    a: [
        row::<0>([]),
        row([1.0 / 5.0]),
        row([3.0 / 40.0, 9.0 / 40.0]),
        row([44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0]),
        row([
            19372.0 / 6561.0,
            -25360.0 / 2187.0,
            64448.0 / 6561.0,
            -212.0 / 729.0,
        ]),
        row([
            9017.0 / 3168.0,
            -355.0 / 33.0,
            46732.0 / 5247.0,
            49.0 / 176.0,
            -5103.0 / 18656.0,
        ]),
        row(DP54_B),
        row::<0>([]),
        row::<0>([]),
        row::<0>([]),
        row::<0>([]),
        row::<0>([]),
    ],
    b: row(DP54_B),
    fsal: true,
    error: ErrorEstimator::Embedded(row([
        71.0 / 57600.0,
        0.0,
        -71.0 / 16695.0,
        71.0 / 1920.0,
        -17253.0 / 339200.0,
        22.0 / 525.0,
        -1.0 / 40.0,
    ])),
    exponent: 0.2,
    interpolant: Some([
        [1.0, -183.0 / 64.0, 37.0 / 12.0, -145.0 / 128.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 1500.0 / 371.0, -1000.0 / 159.0, 1000.0 / 371.0],
        [0.0, -125.0 / 32.0, 125.0 / 12.0, -375.0 / 64.0],
        [0.0, 9477.0 / 3392.0, -729.0 / 106.0, 25515.0 / 6784.0],
        [0.0, -11.0 / 7.0, 11.0 / 3.0, -55.0 / 28.0],
        [0.0, 3.0 / 2.0, -4.0, 5.0 / 2.0],
    ]),
};

/// DOP853 (Dormand & Prince; Hairer, Norsett & Wanner, *Solving ODEs I*, II.10): order 8
/// in twelve stages (no FSAL), error estimators of orders 5 and 3.
pub const DOP853: Tableau = Tableau {
    name: "DOP853",
    stages: 12,
    a: d8::A,
    b: d8::B,
    fsal: false,
    error: ErrorEstimator::FifthAndThird {
        e5: d8::E5,
        e3: d8::E3,
    },
    exponent: 0.125,
    interpolant: None,
};
