//! The model a fit compares with a measurement: the replay of one render's path records at a
//! vector of parameters ([`speckle_estimators::PathRecords::replay`]), turned into the measured
//! quantity (`|g1|`, `g2` or intensities), with its derivatives.

use crate::FitError;
use num_complex::Complex64;
use speckle_estimators::{Derivative, Parameters, PathRecords, Replayed};
use speckle_scene::build::fit::{FitField, FitParameter, Quantity};

/// The measured quantity as a function of the fitted parameters.
#[derive(Debug, Clone)]
pub struct Model<'a> {
    records: &'a PathRecords,
    quantity: Quantity,
    /// The pair of a curve (the records' index).
    pair: usize,
    /// The fitted parameters.
    parameters: &'a [FitParameter],
    /// The lags replayed: 0 first, then the measurement's (curves), or `[0]` (intensities).
    lags: Vec<f64>,
    /// For each measured point: its lag's index in `lags` (curves) or its pair (intensities).
    points: Vec<usize>,
    /// The derivatives asked of each replay, and for each parameter which of them add up to
    /// its derivative (a uniform diffusion is the sum over materials).
    derivatives: Vec<Derivative>,
    uses: Vec<Vec<usize>>,
    groups: usize,
}

/// The model's values at one vector of parameters: the predictions at the measured points,
/// their derivatives by each parameter, and the replay (for the groups' values).
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Predictions, one per measured point.
    pub values: Vec<f64>,
    /// `jacobian[i][p]`: the derivative of prediction `i` by parameter `p`.
    pub jacobian: Vec<Vec<f64>>,
    /// The replay.
    pub replayed: Replayed,
}

impl<'a> Model<'a> {
    /// The model of `quantity` (of pair `pair` for a curve) at the measured abscissae `x` (lags,
    /// or pair indices for intensities) with the parameters `parameters`, replayed over
    /// `groups` groups of paths.
    pub fn new(
        records: &'a PathRecords,
        quantity: Quantity,
        pair: usize,
        parameters: &'a [FitParameter],
        x: &[f64],
        groups: usize,
    ) -> Result<Self, FitError> {
        let (lags, points) = match quantity {
            Quantity::Intensity => (vec![0.0], x.iter().map(|&p| p as usize).collect()),
            Quantity::G1 | Quantity::G2 => {
                let mut lags = vec![0.0];
                let mut points = vec![];
                for &t in x {
                    if t == 0.0 {
                        points.push(0);
                    } else {
                        lags.push(t);
                        points.push(lags.len() - 1);
                    }
                }
                (lags, points)
            }
        };
        let mut derivatives = vec![];
        let mut uses = vec![];
        for p in parameters {
            let mut add = |d: Derivative| {
                derivatives.push(d);
                derivatives.len() - 1
            };
            uses.push(match &p.field {
                FitField::Diffusion { materials: None } => (0..records.materials)
                    .map(|m| add(Derivative::Diffusion(m)))
                    .collect(),
                FitField::Diffusion {
                    materials: Some(list),
                } => list
                    .iter()
                    .map(|&m| add(Derivative::Diffusion(m)))
                    .collect(),
                FitField::SigmaS => vec![add(Derivative::SigmaS)],
                FitField::SigmaA => vec![add(Derivative::SigmaA)],
                FitField::Beta | FitField::Scale => vec![],
            });
        }
        if groups as u64 > records.paths {
            return Err(FitError::Invalid(format!(
                "fit.groups: {groups} groups of {} paths",
                records.paths
            )));
        }
        let model = Self {
            records,
            quantity,
            pair,
            parameters,
            lags,
            points,
            derivatives,
            uses,
            groups,
        };
        if let Some(p) = model.pairs().into_iter().find(|&p| !records.recorded(p)) {
            return Err(FitError::Invalid(format!(
                "fit: pair {p}'s contributions were not recorded by the render"
            )));
        }
        Ok(model)
    }

    /// The replay parameters at `theta` (one value per fitted parameter).
    pub fn parameters_at(&self, theta: &[f64]) -> Parameters {
        let mut p = self.records.rendered.clone();
        for (f, &v) in self.parameters.iter().zip(theta) {
            match &f.field {
                FitField::Diffusion { materials: None } => {
                    p.motions.iter_mut().for_each(|m| m.diffusion = v);
                }
                FitField::Diffusion {
                    materials: Some(list),
                } => list.iter().for_each(|&m| p.motions[m].diffusion = v),
                FitField::SigmaS => {
                    let (_, a) = p.coefficients.expect("checked: a homogeneous medium");
                    p.coefficients = Some((v, a));
                }
                FitField::SigmaA => {
                    let (s, _) = p.coefficients.expect("checked: a homogeneous medium");
                    p.coefficients = Some((s, v));
                }
                FitField::Beta | FitField::Scale => {}
            }
        }
        p
    }

    /// The value of the fitted field `field` in `theta`, or `default`.
    fn get(&self, theta: &[f64], field: FitField, default: f64) -> f64 {
        self.parameters
            .iter()
            .position(|p| p.field == field)
            .map_or(default, |i| theta[i])
    }

    /// Replays the records at `theta`.
    pub fn replay(&self, theta: &[f64]) -> Replayed {
        self.records.replay(
            &self.parameters_at(theta),
            &self.lags,
            self.groups,
            &self.derivatives,
        )
    }

    /// The predictions and their derivatives at `theta`, from the groups but `left_out`
    /// (`None`: all) of `replayed` (the replay at `theta`).
    pub fn predict(
        &self,
        theta: &[f64],
        replayed: &Replayed,
        left_out: Option<usize>,
    ) -> (Vec<f64>, Vec<Vec<f64>>) {
        let np = self.parameters.len();
        let value = |j: usize, l: usize, d: usize| replayed.value(j, l, d, left_out);
        // A parameter's derivative of the replayed C at (pair, lag).
        let d_c = |p: usize, j: usize, l: usize| -> Complex64 {
            self.uses[p].iter().map(|&d| value(j, l, 1 + d)).sum()
        };
        let beta = self.get(theta, FitField::Beta, 1.0);
        let scale = self.get(theta, FitField::Scale, 1.0);
        let mut values = Vec::with_capacity(self.points.len());
        let mut jacobian = Vec::with_capacity(self.points.len());
        for &pt in &self.points {
            let mut row = vec![0.0; np];
            match self.quantity {
                Quantity::Intensity => {
                    let c0 = value(pt, 0, 0).re;
                    values.push(scale * c0);
                    for (p, f) in self.parameters.iter().enumerate() {
                        row[p] = match f.field {
                            FitField::Scale => c0,
                            _ => scale * d_c(p, pt, 0).re,
                        };
                    }
                }
                Quantity::G1 | Quantity::G2 => {
                    let j = self.pair;
                    let c0 = value(j, 0, 0).re;
                    let c = value(j, pt, 0);
                    let g1 = c.norm() / c0;
                    // d|g1| = (Re(conj(C) dC) / |C|) / C0 - |C| dC0 / C0^2.
                    let dg1 = |p: usize| -> f64 {
                        let dc = d_c(p, j, pt);
                        let dabs = if c.norm() > 0.0 {
                            (c.conj() * dc).re / c.norm()
                        } else {
                            0.0
                        };
                        dabs / c0 - c.norm() * d_c(p, j, 0).re / (c0 * c0)
                    };
                    if self.quantity == Quantity::G1 {
                        values.push(g1);
                        for (p, r) in row.iter_mut().enumerate() {
                            *r = dg1(p);
                        }
                    } else {
                        values.push(1.0 + beta * g1 * g1);
                        for (p, f) in self.parameters.iter().enumerate() {
                            row[p] = match f.field {
                                FitField::Beta => g1 * g1,
                                _ => 2.0 * beta * g1 * dg1(p),
                            };
                        }
                    }
                }
            }
            jacobian.push(row);
        }
        (values, jacobian)
    }

    /// [`Model::replay`] then [`Model::predict`] over every group.
    pub fn evaluate(&self, theta: &[f64]) -> Evaluation {
        let replayed = self.replay(theta);
        let (values, jacobian) = self.predict(theta, &replayed, None);
        Evaluation {
            values,
            jacobian,
            replayed,
        }
    }

    /// Number of groups of the replays.
    pub fn groups(&self) -> usize {
        self.groups
    }

    /// The pairs the measurement involves (the curve's, or the measured intensities').
    pub fn pairs(&self) -> Vec<usize> {
        match self.quantity {
            Quantity::Intensity => self.points.clone(),
            _ => vec![self.pair],
        }
    }
}
