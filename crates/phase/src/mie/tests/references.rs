//! Published reference values: Wiscombe (1979) tables, MIEV0's test cases, Bohren and
//! Huffman's appendix A.

use super::*;

/// One case of Wiscombe (1979), "Mie scattering calculations: advances in technique and
/// fast, vector-speed computer codes", NCAR/TN-140+STR (doi:10.5065/D6ZP4414), appendix
/// tables, as transcribed in the tests of MIEX-Python (github.com/mlietzow/MIEX-Python,
/// test_miex.py, "see Appendix, A22"): efficiencies and `g` to 6 decimals, `S11 =
/// (|S1|^2 + |S2|^2) / 2` to 6 significant digits and the polarization
/// `(|S2|^2 - |S1|^2) / (|S1|^2 + |S2|^2)` to 4 decimals at 0, 5, ..., 180 degrees.
struct Wiscombe79 {
    x: f64,
    m_im: f64,
    q_ext: f64,
    q_abs: f64,
    q_sca: f64,
    g: f64,
    s11: [f64; 37],
    pol: [f64; 37],
}

// Published data; some values happen to lie near pi/6.
#[allow(clippy::approx_constant)]
const WISCOMBE_79: [Wiscombe79; 6] = [
    Wiscombe79 {
        x: 10.0,
        m_im: 0.0,
        q_ext: 2.881999,
        q_abs: 0.000000,
        q_sca: 2.881999,
        g: 0.742913,
        s11: [
            5.20856e3, 4.28132e3, 2.34775e3, 8.18121e2, 1.49547e2, 1.39195e1, 7.68071e1, 1.28393e2,
            7.89487e1, 2.93697e1, 5.18546e1, 6.31908e1, 3.41567e1, 2.56714e1, 3.20167e1, 2.35919e1,
            1.94168e1, 1.84988e1, 9.17521e0, 9.63035e0, 1.36986e1, 4.85859e0, 2.80440e0, 8.53248e0,
            4.39826e0, 5.70995e0, 1.13872e1, 3.04142e0, 6.75713e0, 2.42055e1, 1.59589e1, 1.61562e1,
            5.82167e1, 6.79231e1, 2.86866e1, 2.49122e1, 4.23766e1,
        ],
        pol: [
            0.0000, -0.0239, -0.0963, -0.2080, -0.2887, 0.4685, 0.0005, -0.0892, -0.0767, 0.7251,
            0.4834, -0.0592, -0.0163, 0.9793, 0.3242, -0.3951, 0.5014, 0.9514, -0.0269, 0.1127,
            0.7525, 0.7257, 0.8993, 0.5987, -0.4844, 0.3364, 0.9396, 0.6460, 0.6282, 0.9286,
            0.7664, -0.4108, 0.2385, 0.5276, 0.6986, 0.0830, 0.0000,
        ],
    },
    Wiscombe79 {
        x: 100.0,
        m_im: 0.0,
        q_ext: 2.094388,
        q_abs: 0.000000,
        q_sca: 2.094388,
        g: 0.818246,
        s11: [
            2.75508e7, 1.06440e5, 5.86911e4, 2.58367e4, 2.02131e4, 1.92755e4, 1.59327e4, 5.38269e3,
            8.66710e3, 5.40267e3, 3.05275e3, 5.10959e3, 1.67021e3, 2.02680e3, 9.60828e2, 1.22361e3,
            3.94465e2, 2.54063e2, 5.05356e2, 5.07283e2, 1.31614e2, 2.22694e2, 1.33922e2, 7.05029e1,
            4.01041e1, 1.00503e2, 1.67811e2, 2.32785e2, 2.43533e2, 2.35398e2, 1.86086e2, 1.21783e3,
            3.53283e3, 2.39888e3, 2.72592e3, 6.22951e2, 4.34048e3,
        ],
        pol: [
            0.0000, -0.0107, 0.0098, 0.0712, -0.0248, -0.0730, -0.0540, 0.2001, 0.0919, -0.1301,
            0.4545, 0.1026, 0.4679, -0.2130, 0.7357, -0.0054, 0.8365, -0.2535, -0.0016, -0.4214,
            -0.5649, -0.3412, 0.3830, -0.0700, -0.8726, 0.1822, 0.5235, 0.4015, 0.3292, 0.0578,
            0.5225, -0.8534, -0.8664, 0.6181, 0.8582, 0.5069, 0.0000,
        ],
    },
    Wiscombe79 {
        x: 1000.0,
        m_im: 0.0,
        q_ext: 2.013945,
        q_abs: 0.000000,
        q_sca: 2.013945,
        g: 0.827882,
        s11: [
            2.53568e11, 4.82785e6, 8.83654e5, 1.63897e6, 1.36169e6, 1.13470e6, 1.03882e6,
            9.29666e5, 8.63859e5, 7.66220e5, 2.66763e5, 3.24223e5, 2.82935e5, 2.37449e5, 1.60593e5,
            5.25112e4, 7.89951e4, 3.06843e4, 2.48427e4, 2.14530e4, 1.06283e4, 1.52392e4, 1.97453e4,
            9.12219e3, 7.14740e3, 7.91914e3, 9.52024e3, 1.09979e4, 6.66722e3, 1.68603e4, 2.11737e4,
            5.59288e3, 2.08814e5, 2.67605e5, 3.92870e5, 2.24420e5, 2.57577e6,
        ],
        pol: [
            0.0000, -0.0455, -0.1300, -0.0275, 0.0909, 0.0469, 0.0701, 0.0406, -0.0202, -0.0694,
            0.5051, 0.1317, -0.0010, -0.1018, -0.0523, 0.3454, -0.0192, -0.3916, 0.0127, -0.8087,
            -0.8588, -0.6411, -0.6625, -0.5131, 0.3474, -0.4821, -0.2850, -0.2910, 0.3604, -0.3089,
            -0.4512, 0.4230, -0.0666, 0.0290, -0.8299, -0.0267, 0.0000,
        ],
    },
    Wiscombe79 {
        x: 10.0,
        m_im: 0.1,
        q_ext: 2.459791,
        q_abs: 1.224646,
        q_sca: 1.235144,
        g: 0.922350,
        s11: [
            3.79171e3, 3.00320e3, 1.41624e3, 3.13014e2, 1.24235e1, 2.96988e1, 2.73164e1, 1.12113e1,
            1.09517e1, 6.07843e0, 2.20902e0, 6.32075e0, 6.46946e0, 2.25394e0, 2.15826e0, 3.92848e0,
            2.99433e0, 1.63623e0, 1.83556e0, 2.09544e0, 1.66228e0, 1.37914e0, 1.53058e0, 1.47431e0,
            1.16521e0, 1.35300e0, 1.74359e0, 1.36826e0, 7.98073e-1, 9.74236e-1, 1.33396e0,
            1.41816e0, 1.48012e0, 1.26487e0, 1.06733e0, 1.72292e0, 2.31818e0,
        ],
        pol: [
            0.0000, -0.0014, -0.0068, -0.0301, -0.6183, -0.2518, -0.2817, -0.7359, -0.6378,
            -0.5132, -0.9235, -0.7194, -0.6077, -0.1744, -0.2426, -0.7454, -0.6373, 0.3019,
            -0.0893, -0.8614, -0.6653, 0.2706, 0.0790, -0.7132, -0.8966, 0.1033, 0.3819, -0.0370,
            -0.6271, 0.0599, 0.3753, 0.1218, -0.2643, -0.6463, -0.8175, -0.2177, 0.0000,
        ],
    },
    Wiscombe79 {
        x: 100.0,
        m_im: 0.1,
        q_ext: 2.089822,
        q_abs: 0.957688,
        q_sca: 1.132134,
        g: 0.950392,
        s11: [
            2.73645e7, 9.11574e4, 1.30172e4, 3.14304e3, 1.21824e3, 9.11319e2, 8.01673e2, 6.29347e2,
            4.65786e2, 3.70932e2, 3.17391e2, 2.69848e2, 2.30451e2, 2.02758e2, 1.80401e2, 1.62813e2,
            1.49203e2, 1.38475e2, 1.30113e2, 1.23599e2, 1.18559e2, 1.14659e2, 1.11687e2, 1.09437e2,
            1.07749e2, 1.06503e2, 1.05600e2, 1.04961e2, 1.04521e2, 1.04229e2, 1.04044e2, 1.03935e2,
            1.03877e2, 1.03850e2, 1.03840e2, 1.03837e2, 1.03837e2,
        ],
        pol: [
            0.0000, -0.0247, -0.0848, -0.2375, -0.4798, -0.5484, -0.5537, -0.6268, -0.7490,
            -0.8418, -0.8905, -0.9395, -0.9797, -0.9960, -0.9944, -0.9750, -0.9395, -0.8885,
            -0.8273, -0.7576, -0.6831, -0.6072, -0.5316, -0.4586, -0.3897, -0.3257, -0.2673,
            -0.2148, -0.1684, -0.1278, -0.0932, -0.0643, -0.0409, -0.0229, -0.0101, -0.0025,
            0.0000,
        ],
    },
    Wiscombe79 {
        x: 1000.0,
        m_im: 0.1,
        q_ext: 2.019703,
        q_abs: 0.912770,
        q_sca: 1.106932,
        g: 0.950880,
        s11: [
            2.55002e11, 1.03489e6, 2.70449e5, 1.45265e5, 1.01955e5, 8.03929e4, 6.46676e4,
            5.28211e4, 4.36516e4, 3.64909e4, 3.08618e4, 2.64252e4, 2.29245e4, 2.01609e4, 1.79799e4,
            1.62601e4, 1.49061e4, 1.38426e4, 1.30097e4, 1.23601e4, 1.18559e4, 1.14671e4, 1.11696e4,
            1.09441e4, 1.07752e4, 1.06505e4, 1.05601e4, 1.04961e4, 1.04520e4, 1.04227e4, 1.04042e4,
            1.03933e4, 1.03874e4, 1.03846e4, 1.03836e4, 1.03834e4, 1.03834e4,
        ],
        pol: [
            0.0000, -0.0682, -0.1681, -0.2830, -0.3931, -0.4861, -0.5789, -0.6682, -0.7517,
            -0.8267, -0.8909, -0.9417, -0.9765, -0.9939, -0.9928, -0.9737, -0.9379, -0.8878,
            -0.8265, -0.7571, -0.6829, -0.6069, -0.5315, -0.4586, -0.3897, -0.3258, -0.2674,
            -0.2149, -0.1684, -0.1279, -0.0932, -0.0643, -0.0409, -0.0229, -0.0101, -0.0025,
            0.0000,
        ],
    },
];

#[test]
fn wiscombe_1979_tables_m_1_5_and_1_5_plus_0_1i() {
    for case in &WISCOMBE_79 {
        let mie = sphere(case.x, c(1.5, case.m_im));
        let what = |q: &str| format!("x = {}, m = 1.5 + {}i: {q}", case.x, case.m_im);
        assert_decimals(&what("Q_ext"), mie.q_ext(), case.q_ext, 6);
        assert_decimals(&what("Q_abs"), mie.q_abs(), case.q_abs, 6);
        assert_decimals(&what("Q_sca"), mie.q_sca(), case.q_sca, 6);
        assert_decimals(&what("g"), mie.asymmetry(), case.g, 6);
        for (i, (&s11, &pol)) in case.s11.iter().zip(&case.pol).enumerate() {
            let deg = 5 * i;
            let (s1, s2) = mie.s1_s2((deg as f64).to_radians().cos());
            let (i1, i2) = (s1.norm_sqr(), s2.norm_sqr());
            assert_printed(&what(&format!("S11({deg} deg)")), 0.5 * (i1 + i2), s11, 6);
            let p = (i2 - i1) / (i1 + i2);
            assert_decimals(&what(&format!("pol({deg} deg)")), p, pol, 4);
        }
    }
}

#[test]
fn wiscombe_1979_x_5000() {
    // Same source as WISCOMBE_79 (x = 5000 tables).
    let mie = sphere(5000.0, c(1.5, 0.0));
    assert_decimals("Q_ext", mie.q_ext(), 2.008650, 6);
    assert_decimals("Q_sca", mie.q_sca(), 2.008650, 6);
    assert_decimals("g", mie.asymmetry(), 0.829592, 6);
    let mie = sphere(5000.0, c(1.5, 0.1));
    assert_decimals("Q_ext", mie.q_ext(), 2.006775, 6);
    assert_decimals("Q_abs", mie.q_abs(), 0.907582, 6);
    assert_decimals("Q_sca", mie.q_sca(), 1.099193, 6);
    assert_decimals("g", mie.asymmetry(), 0.950650, 6);
}

/// One test case of Wiscombe's MIEV0 test driver (MVTstNew.f, the answers distributed with
/// MIEV0): `Q_ext`, `Q_sca`, `g Q_sca` and `S1, S2` at 0, 30, ..., 180 degrees, 7
/// significant digits. Efficiencies as transcribed in `mieQvalsTest.m` (arrays TestQE,
/// TestQS, TestGQ, "Wiscombe's tabulated values in MVTstNew.f"); amplitudes as transcribed
/// in usask-arg/sasktran2 lib/tests/mie/linearized_mie.cpp ("MIEV0 Test Case N"), leaving
/// out the angles where that file replaced Wiscombe's values by miepython's (120-180 deg
/// for case 11, 180 deg for cases 16 and 19). MIEV0 uses `exp(+i omega t)`: `Im m <= 0`
/// there and its `S` are the complex conjugates of ours; `m` below is in our convention.
struct Miev0 {
    case: u32,
    x: f64,
    m: (f64, f64),
    q_ext: f64,
    q_sca: f64,
    g_q_sca: f64,
    /// `[Re S1, Im S1, Re S2, Im S2]` in Wiscombe's convention.
    s: &'static [[f64; 4]],
}

const MIEV0: [Miev0; 15] = [
    // MIEV0 test case 5.
    Miev0 {
        case: 5,
        x: 0.099,
        m: (0.75, 0.0),
        q_ext: 7.417859e-6,
        q_sca: 7.417859e-6,
        g_q_sca: 1.074279e-8,
        s: &[
            [1.817558e-8, -1.654225e-4, 1.817558e-8, -1.654225e-4],
            [1.817558e-8, -1.653815e-4, 1.574051e-8, -1.432172e-4],
            [1.817558e-8, -1.652694e-4, 9.087788e-9, -8.261265e-5],
            [1.817558e-8, -1.651163e-4, 9.797186e-23, 2.938374e-8],
            [1.817558e-8, -1.649631e-4, -9.087788e-9, 8.250360e-5],
            [1.817558e-8, -1.648510e-4, -1.574051e-8, 1.427725e-4],
            [1.817558e-8, -1.648100e-4, -1.817558e-8, 1.648100e-4],
        ],
    },
    // MIEV0 test case 6.
    Miev0 {
        case: 6,
        x: 0.101,
        m: (0.75, 0.0),
        q_ext: 8.033542e-6,
        q_sca: 8.033542e-6,
        g_q_sca: 1.211000e-8,
        s: &[
            [2.048754e-8, -1.756419e-4, 2.048754e-8, -1.756419e-4],
            [2.048754e-8, -1.755965e-4, 1.774273e-8, -1.520629e-4],
            [2.048753e-8, -1.754726e-4, 1.024377e-8, -8.771198e-5],
            [2.048751e-8, -1.753033e-4, 1.845057e-15, 3.247270e-8],
            [2.048750e-8, -1.751341e-4, -1.024375e-8, 8.759147e-5],
            [2.048749e-8, -1.750103e-4, -1.774269e-8, 1.515715e-4],
            [2.048749e-8, -1.749650e-4, -2.048749e-8, 1.749650e-4],
        ],
    },
    // MIEV0 test case 7.
    Miev0 {
        case: 7,
        x: 10.0,
        m: (0.75, 0.0),
        q_ext: 2.232265,
        q_sca: 2.232265,
        g_q_sca: 2.001164,
        s: &[
            [5.580662e1, -9.758097, 5.580662e1, -9.758097],
            [-7.672879, 1.087317e1, -1.092923e1, 9.629667],
            [3.587894, -1.756177, 3.427411, 8.082691e-2],
            [-1.785905, -5.232828e-2, -5.148748e-1, -7.027288e-1],
            [1.537971, -8.329374e-2, -6.908338e-1, 2.152693e-1],
            [-4.140427e-1, 1.876851e-1, 5.247557e-1, -1.923391e-1],
            [-1.078568, -3.608807e-2, 1.078568, 3.608807e-2],
        ],
    },
    // MIEV0 test case 8.
    Miev0 {
        case: 8,
        x: 1000.0,
        m: (0.75, 0.0),
        q_ext: 1.997908,
        q_sca: 1.997908,
        g_q_sca: 1.688121,
        s: &[
            [4.994770e5, -1.336502e4, 4.994770e5, -1.336502e4],
            [-3.999296e2, -3.316361e2, -3.946018e2, -1.147791e2],
            [-5.209852e2, -5.776614e2, -1.970767e2, -6.937470e2],
            [-1.600887e2, 1.348013e2, -4.152365e1, 1.143000e2],
            [8.431720e1, -1.209493e2, -4.261732e1, 5.535055e1],
            [-7.556092e1, -8.134810e1, 4.218303e1, 9.100831e1],
            [1.705778e1, 4.842510e2, -1.705778e1, -4.842510e2],
        ],
    },
    // MIEV0 test case 9.
    Miev0 {
        case: 9,
        x: 1.0,
        m: (1.33, 1e-05),
        q_ext: 9.395198e-2,
        q_sca: 9.392330e-2,
        g_q_sca: 1.733048e-2,
        s: &[
            [2.348800e-2, 2.281705e-1, 2.348800e-2, 2.281705e-1],
            [2.341722e-2, 2.217102e-1, 2.034830e-2, 1.938171e-1],
            [2.322408e-2, 2.046815e-1, 1.181704e-2, 1.075976e-1],
            [2.296081e-2, 1.828349e-1, 2.729533e-4, 6.702879e-3],
            [2.269820e-2, 1.625401e-1, -1.114466e-2, -7.646326e-2],
            [2.250635e-2, 1.486170e-1, -1.942300e-2, -1.271557e-1],
            [2.243622e-2, 1.437106e-1, -2.243622e-2, -1.437106e-1],
        ],
    },
    // MIEV0 test case 10.
    Miev0 {
        case: 10,
        x: 100.0,
        m: (1.33, 1e-05),
        q_ext: 2.101321,
        q_sca: 2.096594,
        g_q_sca: 1.821854,
        s: &[
            [5.253302e3, -1.243188e2, 5.253302e3, -1.243188e2],
            [-5.534573e1, -2.971881e1, -8.467204e1, -1.999470e1],
            [1.710488e1, -1.520096e1, 3.310764e1, -2.709787],
            [-3.655758, 8.769860, -6.550512, -4.675370],
            [2.414318, 5.380874e-1, 6.039011, -1.169971e1],
            [-1.222996, 3.283917e1, -9.653812, 1.474455e1],
            [-5.659205e1, 4.650974e1, 5.659205e1, -4.650974e1],
        ],
    },
    // MIEV0 test case 11.
    Miev0 {
        case: 11,
        x: 10000.0,
        m: (1.33, 1e-05),
        q_ext: 2.004089,
        q_sca: 1.723857,
        g_q_sca: 1.564987,
        s: &[
            [5.010222e7, -1.535815e5, 5.010222e7, -1.535815e5],
            [3.786814e3, -7.654293e3, 5.074755e3, -7.515986e3],
            [-2.731172e3, 1.326633e3, -3.076558e3, -1.775975e2],
            [-1.061003e3, -1.930155e2, 2.430920e2, 8.409836e1],
        ],
    },
    // MIEV0 test case 12.
    Miev0 {
        case: 12,
        x: 0.055,
        m: (1.5, 1.0),
        q_ext: 1.014910e-1,
        q_sca: 1.131687e-5,
        g_q_sca: 5.558541e-9,
        s: &[
            [7.675259e-5, 8.343879e-5, 7.675259e-5, 8.343879e-5],
            [7.674331e-5, 8.343495e-5, 6.646948e-5, 7.225169e-5],
            [7.671794e-5, 8.342445e-5, 3.838246e-5, 4.169695e-5],
            [7.668328e-5, 8.341012e-5, 3.132066e-8, -2.037399e-8],
            [7.664863e-5, 8.339578e-5, -3.830082e-5, -4.171317e-5],
            [7.662326e-5, 8.338529e-5, -6.634986e-5, -7.221887e-5],
            [7.661398e-5, 8.338145e-5, -7.661398e-5, -8.338145e-5],
        ],
    },
    // MIEV0 test case 13.
    Miev0 {
        case: 13,
        x: 0.056,
        m: (1.5, 1.0),
        q_ext: 1.033467e-1,
        q_sca: 1.216311e-5,
        g_q_sca: 6.193255e-9,
        s: &[
            [8.102381e-5, 8.807251e-5, 8.102381e-5, 8.807251e-5],
            [8.101364e-5, 8.806830e-5, 7.016844e-5, 7.626381e-5],
            [8.098587e-5, 8.805682e-5, 4.051865e-5, 4.401169e-5],
            [8.094795e-5, 8.804113e-5, 3.427277e-8, -2.229631e-8],
            [8.091003e-5, 8.802545e-5, -4.042932e-5, -4.402945e-5],
            [8.088228e-5, 8.801396e-5, -7.003755e-5, -7.622790e-5],
            [8.087213e-5, 8.800976e-5, -8.087213e-5, -8.800976e-5],
        ],
    },
    // MIEV0 test case 14.
    Miev0 {
        case: 14,
        x: 1.0,
        m: (1.5, 1.0),
        q_ext: 2.336321,
        q_sca: 6.634538e-1,
        g_q_sca: 1.274736e-1,
        s: &[
            [5.840802e-1, 1.905153e-1, 5.840802e-1, 1.905153e-1],
            [5.657020e-1, 1.871997e-1, 5.001610e-1, 1.456112e-1],
            [5.175251e-1, 1.784426e-1, 2.879639e-1, 4.105398e-2],
            [4.563396e-1, 1.671665e-1, 3.622847e-2, -6.182646e-2],
            [4.002117e-1, 1.566427e-1, -1.748750e-1, -1.229586e-1],
            [3.621572e-1, 1.493910e-1, -3.056823e-1, -1.438460e-1],
            [3.488438e-1, 1.468286e-1, -3.488438e-1, -1.468286e-1],
        ],
    },
    // MIEV0 test case 15.
    Miev0 {
        case: 15,
        x: 100.0,
        m: (1.5, 1.0),
        q_ext: 2.097502,
        q_sca: 1.283697,
        g_q_sca: 1.091466,
        s: &[
            [5.243754e3, -2.934167e2, 5.243754e3, -2.934167e2],
            [4.049055e1, -1.898456e1, 2.019198e1, 3.110731],
            [-2.646835e1, -1.929564e1, 9.152743, -7.470202],
            [1.268890e1, 2.397474e1, -1.232914e1, -7.823167],
            [5.149886, 2.290736e1, -7.173357, -1.655464e1],
            [-1.605395e1, 1.418642e1, 1.448052e1, -1.393594e1],
            [-2.029360e1, 4.384435, 2.029360e1, -4.384435],
        ],
    },
    // MIEV0 test case 16.
    Miev0 {
        case: 16,
        x: 10000.0,
        m: (1.5, 1.0),
        q_ext: 2.004368,
        q_sca: 1.236574,
        g_q_sca: 1.046525,
        s: &[
            [5.010919e7, -1.753404e5, 5.010919e7, -1.753404e5],
            [-3.690394e3, -1.573897e3, -9.333175e2, -1.839736e3],
            [2.391551e2, 3.247786e3, -1.202951e3, -1.899647e2],
            [-2.607463e3, 7.414859e2, 1.013073e3, -1.064666e3],
            [-6.183154e2, 2.264970e3, 1.334826e2, -1.800859e3],
            [-3.368019e2, 2.115750e3, 2.293862e2, -1.996754e3],
        ],
    },
    // MIEV0 test case 17.
    Miev0 {
        case: 17,
        x: 1.0,
        m: (10.0, 10.0),
        q_ext: 2.532993,
        q_sca: 2.049405,
        g_q_sca: -2.267961e-1,
        s: &[
            [6.332483e-1, 4.179305e-1, 6.332483e-1, 4.179305e-1],
            [6.162264e-1, 4.597163e-1, 5.573186e-1, 2.954338e-1],
            [5.736317e-1, 5.602514e-1, 3.525107e-1, -5.921611e-3],
            [5.238628e-1, 6.675352e-1, 7.881172e-2, -3.435544e-1],
            [4.825816e-1, 7.434033e-1, -1.881212e-1, -6.028739e-1],
            [4.570214e-1, 7.809867e-1, -3.793898e-1, -7.473279e-1],
            [4.485464e-1, 7.912365e-1, -4.485464e-1, -7.912365e-1],
        ],
    },
    // MIEV0 test case 18.
    Miev0 {
        case: 18,
        x: 100.0,
        m: (10.0, 10.0),
        q_ext: 2.071124,
        q_sca: 1.836785,
        g_q_sca: 1.021648,
        s: &[
            [5.177811e3, -2.633811e1, 5.177811e3, -2.633811e1],
            [5.227436e1, -1.270012e1, -2.380252e1, -3.872567e-1],
            [-2.705712e1, -3.951751e1, 2.585821e1, 3.323624e1],
            [1.008860, 4.663027e1, -3.479935, -4.364245e1],
            [-1.505640e1, 4.333057e1, 1.360634e1, -4.238302e1],
            [-4.510770e1, 5.199554, 4.474564e1, -5.452513],
            [-4.145383e1, -1.821808e1, 4.145383e1, 1.821808e1],
        ],
    },
    // MIEV0 test case 19.
    Miev0 {
        case: 19,
        x: 10000.0,
        m: (10.0, 10.0),
        q_ext: 2.005914,
        q_sca: 1.795393,
        g_q_sca: 9.842238e-1,
        s: &[
            [5.014786e7, -1.206004e5, 5.014786e7, -1.206004e5],
            [-4.080090e3, -2.664399e3, 3.351286e3, 7.291906e2],
            [-1.224040e3, 4.596569e3, 4.497446e2, -4.072999e3],
            [-4.579490e3, -8.590486e2, 4.313394e3, 4.969719e2],
            [-3.356286e3, 3.125121e3, 3.171910e3, -3.129068e3],
            [-3.149584e3, 3.270358e3, 3.105243e3, -3.269355e3],
        ],
    },
];

/// Compares with MIEV0 to `digits` significant digits, or, when `relative` is given, with
/// that relative tolerance on each efficiency, and that fraction of `|S(0)|` on each complex
/// amplitude.
fn check_miev0(case: &Miev0, digits: i32, relative: Option<f64>) {
    let mie = sphere(case.x, c(case.m.0, case.m.1));
    let what = |q: &str| format!("MIEV0 case {} (x = {}): {q}", case.case, case.x);
    let gq = mie.asymmetry() * mie.q_sca();
    for (name, ours, theirs) in [
        ("Q_ext", mie.q_ext(), case.q_ext),
        ("Q_sca", mie.q_sca(), case.q_sca),
        ("g Q_sca", gq, case.g_q_sca),
    ] {
        match relative {
            None => assert_printed(&what(name), ours, theirs, digits),
            Some(tol) => assert!((ours / theirs - 1.0).abs() < tol, "{}", what(name)),
        }
    }
    for (i, s) in case.s.iter().enumerate() {
        let deg = 30 * i;
        let (s1, s2) = mie.s1_s2((deg as f64).to_radians().cos());
        // Wiscombe's amplitudes are the complex conjugates of Bohren & Huffman's.
        let (w1, w2) = (c(s[0], -s[1]), c(s[2], -s[3]));
        match relative {
            None => {
                let ours = [s1.re, s1.im, s2.re, s2.im];
                let theirs = [w1.re, w1.im, w2.re, w2.im];
                let names = ["Re S1", "Im S1", "Re S2", "Im S2"];
                for k in 0..4 {
                    let name = format!("{} ({deg} deg)", names[k]);
                    assert_printed(&what(&name), ours[k], theirs[k], digits);
                }
            }
            Some(tol) => {
                let scale = c(case.s[0][0], case.s[0][1]).norm();
                let e = (s1 - w1).norm().max((s2 - w2).norm()) / scale;
                assert!(e < tol, "{}: {e:e}", what(&format!("S at {deg} deg")));
            }
        }
    }
}

#[test]
fn miev0_test_cases_to_six_digits() {
    // All printed values agree to 6 significant digits, and to all 7 except 4 amplitude
    // components that are off by 0.50 to 0.70 units of the 7th digit (cases 11 and 13), where
    // a 40-digit evaluation (mpmath Bessel functions) agrees with this code, not with MIEV0.
    for case in MIEV0.iter().filter(|c| ![5, 6, 12].contains(&c.case)) {
        check_miev0(case, 6, None);
    }
}

#[test]
fn miev0_cases_5_6_and_12_to_two_parts_per_million() {
    // Cases 5 (x = 0.099) and 12 (x = 0.055, |m| x = 0.099): MIEV0 switches to its
    // small-particle expansion (Wiscombe 1980) when x and |m| x are both below 0.1, so these
    // values carry that expansion's truncation error; its twin cases 6 and 13, just above the
    // threshold, test the full series. Case 6 (x = 0.101) nevertheless deviates from this code
    // by up to 1.1e-6 relative (Q_ext 8.033542e-6 vs 8.0335381e-6; Im S2(60 deg)): Du, Appl.
    // Opt. 43, 1951 (2004), Table 1, lists Q_ext = 8.033538e-6 for it, and a 40-digit
    // evaluation with mpmath's Bessel functions agrees with this code to 10 digits
    // (Q_ext = 8.03353814856e-6; S2(60 deg) = 1.02437593754e-8 + 8.77118828784e-5 i in
    // our convention). Observed: efficiencies within 1.6e-6 relative, amplitudes within
    // 1e-6 |S(0)|.
    for case in MIEV0.iter().filter(|c| [5, 6, 12].contains(&c.case)) {
        check_miev0(case, 0, Some(2e-6));
    }
}

#[test]
#[allow(clippy::approx_constant)] // published data (0.785390 is not meant as pi/4)
fn bohren_huffman_appendix_a_example() {
    // Bohren & Huffman (1983), appendix A (BHMIE example output, p. 482): m = 1.55,
    // radius 0.525 um, wavelength 0.6328 um, in vacuum (x = 5.213); as transcribed in
    // MIEX-Python test_miex.py (test_bh) and miepython's tests. S11 is normalised to its
    // forward value, POL = -S12 / S11, S33 / S11, S34 / S11 at 0, 9, ..., 180 degrees.
    let mie = MieSphere::new(0.525, c(1.55, 0.0), 1.0, 0.6328).unwrap();
    assert_printed("Q_ext", mie.q_ext(), 3.10543, 6);
    assert_printed("Q_sca", mie.q_sca(), 3.10543, 6);
    assert_printed("Q_back", mie.q_back(), 2.92534, 6);
    let table: [[f64; 4]; 21] = [
        [1.00000e0, 0.0, 1.00000e0, 0.0],
        [7.85390e-1, -4.59811e-3, 9.99400e-1, 3.43261e-2],
        [3.56897e-1, -4.58541e-2, 9.86022e-1, 1.60184e-1],
        [7.66119e-2, -3.64744e-1, 8.43603e-1, 3.94076e-1],
        [3.55355e-2, -5.34997e-1, 6.86967e-1, -4.91787e-1],
        [7.01845e-2, 9.59953e-3, 9.59825e-1, -2.80434e-1],
        [5.74313e-2, 4.77927e-2, 9.85371e-1, 1.63584e-1],
        [2.19660e-2, -4.40604e-1, 6.48043e-1, 6.21216e-1],
        [1.25959e-2, -8.31996e-1, 2.03255e-1, -5.16208e-1],
        [1.73750e-2, 3.41670e-2, 7.95354e-1, -6.05182e-1],
        [1.24601e-2, 2.30462e-1, 9.37497e-1, 2.60742e-1],
        [6.79093e-3, -7.13472e-1, -7.17397e-3, 7.00647e-1],
        [9.54239e-3, -7.56255e-1, -3.94748e-2, -6.53085e-1],
        [8.63419e-3, -2.81215e-1, 5.36251e-1, -7.95835e-1],
        [2.27421e-3, -2.39612e-1, 9.67602e-1, 7.95798e-2],
        [5.43998e-3, -8.50804e-1, 1.87531e-1, -4.90882e-1],
        [1.60243e-2, -7.06334e-1, 4.95254e-1, -5.05781e-1],
        [1.88852e-2, -8.91081e-1, 4.53277e-1, -2.26817e-2],
        [1.95254e-2, -7.83319e-1, -3.91613e-1, 4.82752e-1],
        [3.01676e-2, -1.96194e-1, -9.62069e-1, 1.89556e-1],
        [3.83189e-2, 0.0, -1.00000e0, 0.0],
    ];
    // BHMIE works in single precision (complex arithmetic with eps ~ 6e-8), and two of its
    // printed ratios (S33/S11 at 99 deg, -7.17397e-3, and S34/S11 at 126 deg, 7.95798e-2)
    // are off by 0.54 and 0.56 units of their 6th digit from a 40-digit mpmath evaluation
    // (-7.173975384e-3, 7.957985618e-2), which this code matches: compare to within one
    // unit of the last printed digit.
    let (f1, f2) = mie.s1_s2(1.0);
    let s11_0 = 0.5 * (f1.norm_sqr() + f2.norm_sqr());
    for (i, row) in table.iter().enumerate() {
        let deg = 9 * i;
        let (s1, s2) = mie.s1_s2((deg as f64).to_radians().cos());
        let s11 = 0.5 * (s1.norm_sqr() + s2.norm_sqr());
        let s12 = 0.5 * (s2.norm_sqr() - s1.norm_sqr());
        let s33 = (s2 * s1.conj()).re;
        let s34 = (s2 * s1.conj()).im;
        let what = |q: &str| format!("BH example, {q} at {deg} deg");
        assert_printed_units(&what("S11/S11(0)"), s11 / s11_0, row[0], 6, 1.0);
        if row[1] != 0.0 {
            assert_printed_units(&what("POL"), -s12 / s11, row[1], 6, 1.0);
            assert_printed_units(&what("S34/S11"), s34 / s11, row[3], 6, 1.0);
        }
        assert_printed_units(&what("S33/S11"), s33 / s11, row[2], 6, 1.0);
    }
}

// ---------------------------------------------------------------------------------------
// Small particles.
