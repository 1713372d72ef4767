//! Spec strings: parsing `name:key=value,...` into a [`KernelSpec`] and
//! writing it back.

use std::fmt;
use std::str::FromStr;

use super::{DerivOrder, KernelError, KernelSpec, MAX_RADIUS};

/// Parsed `key=value` pairs of one spec, consumed key by key.
pub(super) struct Keys {
    spec: String,
    pairs: Vec<(String, String)>,
}

impl Keys {
    pub(super) fn take(&mut self, key: &str) -> Option<String> {
        let i = self.pairs.iter().position(|(k, _)| k == key)?;
        Some(self.pairs.remove(i).1)
    }

    pub(super) fn num(&mut self, key: &'static str) -> Result<Option<f64>, KernelError> {
        let Some(v) = self.take(key) else {
            return Ok(None);
        };
        let x: f64 = v.trim().parse().map_err(|_| KernelError::BadValue {
            key: key.to_string(),
            value: v.clone(),
            reason: "not a number".into(),
        })?;
        if !x.is_finite() {
            return Err(KernelError::BadValue {
                key: key.to_string(),
                value: v,
                reason: "not finite".into(),
            });
        }
        // an angle that large has lost its degrees to rounding
        if key == "theta" && x.abs() > 1e6 {
            return Err(KernelError::BadValue {
                key: key.to_string(),
                value: v,
                reason: "use an angle within +-1e6 degrees".into(),
            });
        }
        Ok(Some(x))
    }

    pub(super) fn positive(&mut self, key: &'static str) -> Result<Option<f64>, KernelError> {
        match self.num(key)? {
            Some(x) if x <= 0.0 => Err(KernelError::BadValue {
                key: key.to_string(),
                value: format!("{x}"),
                reason: "must be positive".into(),
            }),
            other => Ok(other),
        }
    }

    pub(super) fn required(&mut self, key: &'static str) -> Result<f64, KernelError> {
        self.positive(key)?.ok_or_else(|| KernelError::MissingKey {
            spec: self.spec.clone(),
            key,
        })
    }

    pub(super) fn radius(&mut self, alias_r: bool) -> Result<Option<usize>, KernelError> {
        let mut value = self.take("radius");
        if alias_r && value.is_none() {
            value = self.take("r");
        }
        let Some(v) = value else { return Ok(None) };
        let n: usize = v.trim().parse().map_err(|_| KernelError::BadValue {
            key: "radius".into(),
            value: v.clone(),
            reason: "not a non-negative integer".into(),
        })?;
        if n > MAX_RADIUS {
            return Err(KernelError::TooLarge { radius: n as f64 });
        }
        Ok(Some(n))
    }

    pub(super) fn finish(self, known: &str) -> Result<(), KernelError> {
        match self.pairs.into_iter().next() {
            None => Ok(()),
            Some((key, _)) => Err(KernelError::UnknownKey {
                spec: self.spec,
                key,
                known: known.to_string(),
            }),
        }
    }
}

impl FromStr for KernelSpec {
    type Err = KernelError;

    fn from_str(s: &str) -> Result<Self, KernelError> {
        let s = s.trim();
        let (name, rest) = s.split_once(':').unwrap_or((s, ""));
        let name = name.trim().to_ascii_lowercase();
        let mut pairs = Vec::new();
        for item in rest.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            let Some((k, v)) = item.split_once('=') else {
                return Err(KernelError::Syntax {
                    spec: s.to_string(),
                    reason: format!("{item:?} is not key=value"),
                });
            };
            let k = k.trim().to_string();
            if pairs.iter().any(|(p, _): &(String, String)| *p == k) {
                return Err(KernelError::Syntax {
                    spec: s.to_string(),
                    reason: format!("key {k:?} given twice"),
                });
            }
            pairs.push((k, v.trim().to_string()));
        }
        let mut keys = Keys {
            spec: name.clone(),
            pairs,
        };
        let spec = match name.as_str() {
            "gauss" => {
                let sx = keys.required("sx")?;
                let sy = keys.positive("sy")?.unwrap_or(sx);
                let theta = keys.num("theta")?.unwrap_or(0.0);
                let radius = keys.radius(true)?;
                keys.finish("sx, sy, theta, radius/r")?;
                Self::Gauss {
                    sx,
                    sy,
                    theta,
                    radius,
                }
            }
            "dgauss" => {
                let order = match keys.take("order").as_deref() {
                    Some("xx") => DerivOrder::Xx,
                    Some("xy" | "yx") => DerivOrder::Xy,
                    Some("yy") => DerivOrder::Yy,
                    Some(other) => {
                        return Err(KernelError::BadValue {
                            key: "order".into(),
                            value: other.to_string(),
                            reason: "expected xx, xy or yy".into(),
                        });
                    }
                    None => {
                        return Err(KernelError::MissingKey {
                            spec: name,
                            key: "order",
                        });
                    }
                };
                let sigma = keys.required("sigma")?;
                let theta = keys.num("theta")?.unwrap_or(0.0);
                let radius = keys.radius(true)?;
                keys.finish("order, sigma, theta, radius/r")?;
                Self::DGauss {
                    order,
                    sigma,
                    theta,
                    radius,
                }
            }
            "log" => {
                let sigma = keys.required("sigma")?;
                let radius = keys.radius(true)?;
                keys.finish("sigma, radius/r")?;
                Self::Log { sigma, radius }
            }
            "gabor" => {
                let sigma = keys.required("sigma")?;
                let freq = keys.num("freq")?.ok_or(KernelError::MissingKey {
                    spec: name.clone(),
                    key: "freq",
                })?;
                if freq.abs() > 0.5 {
                    return Err(KernelError::BadValue {
                        key: "freq".into(),
                        value: format!("{freq}"),
                        reason: "above 0.5 cycles per pixel (the Nyquist frequency): sampled \
                                 at pixels it would alias to a lower one"
                            .into(),
                    });
                }
                let theta = keys.num("theta")?.unwrap_or(0.0);
                let radius = keys.radius(true)?;
                keys.finish("sigma, freq, theta, radius/r")?;
                Self::Gabor {
                    sigma,
                    freq,
                    theta,
                    radius,
                }
            }
            "box" => {
                let w = keys.required("w")?;
                let h = keys.positive("h")?.unwrap_or(w);
                let theta = keys.num("theta")?.unwrap_or(0.0);
                let radius = keys.radius(true)?;
                keys.finish("w, h, theta, radius/r")?;
                Self::Box {
                    w,
                    h,
                    theta,
                    radius,
                }
            }
            "disk" => {
                let r = keys.required("r")?;
                let radius = keys.radius(false)?;
                keys.finish("r, radius")?;
                Self::Disk { r, radius }
            }
            "line" => {
                let len = keys.required("len")?;
                let width = keys.positive("width")?.unwrap_or(1.0);
                let theta = keys.num("theta")?.unwrap_or(0.0);
                let radius = keys.radius(true)?;
                keys.finish("len, width, theta, radius/r")?;
                Self::Line {
                    len,
                    width,
                    theta,
                    radius,
                }
            }
            _ => return Err(KernelError::UnknownSpec { name }),
        };
        spec.check_size()?;
        Ok(spec)
    }
}

impl fmt::Display for KernelSpec {
    /// The canonical spec string (parses back to the same spec).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let radius = |r: &Option<usize>| r.map(|r| format!(",radius={r}")).unwrap_or_default();
        match self {
            Self::Gauss {
                sx,
                sy,
                theta,
                radius: r,
            } => write!(f, "gauss:sx={sx},sy={sy},theta={theta}{}", radius(r)),
            Self::DGauss {
                order,
                sigma,
                theta,
                radius: r,
            } => {
                let o = match order {
                    DerivOrder::Xx => "xx",
                    DerivOrder::Xy => "xy",
                    DerivOrder::Yy => "yy",
                };
                write!(
                    f,
                    "dgauss:order={o},sigma={sigma},theta={theta}{}",
                    radius(r)
                )
            }
            Self::Log { sigma, radius: r } => write!(f, "log:sigma={sigma}{}", radius(r)),
            Self::Gabor {
                sigma,
                freq,
                theta,
                radius: r,
            } => write!(
                f,
                "gabor:sigma={sigma},freq={freq},theta={theta}{}",
                radius(r)
            ),
            Self::Box {
                w,
                h,
                theta,
                radius: r,
            } => write!(f, "box:w={w},h={h},theta={theta}{}", radius(r)),
            Self::Disk { r, radius: rr } => write!(f, "disk:r={r}{}", radius(rr)),
            Self::Line {
                len,
                width,
                theta,
                radius: r,
            } => write!(f, "line:len={len},width={width},theta={theta}{}", radius(r)),
        }
    }
}
