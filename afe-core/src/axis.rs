//! The axes of a signal's frame: what each index along them stands for, with its value,
//! so that a consumer labels and draws an output from its description alone.

use serde::ser::{Serialize, SerializeMap, Serializer};

/// One axis of a frame (the axes after time), with the value at each index.
#[derive(Debug, Clone, PartialEq)]
pub enum Axis {
    /// Frequency channels, by centre frequency in Hz.
    Channels(Vec<f64>),
    /// Spectrum bins, by frequency in Hz.
    Bins(Vec<f64>),
    /// Correlation lags in s.
    Lags(Vec<f64>),
    /// Modulation channels, by centre frequency in Hz.
    Modulation(Vec<f64>),
    /// Named features, in output order.
    Features(Vec<String>),
    /// Directions by head-relative azimuth in degrees (0 = front, 90 = left, as in SOFA).
    Azimuth(Vec<f64>),
    /// DUET's attenuation bins, `|ρ| − 1/|ρ|` for the ear ratio `ρ`.
    Attenuation(Vec<f64>),
    /// DUET's delay bins, in samples at the audio rate.
    Delay(Vec<f64>),
    /// An axis the engine has no kind for, described by the processor that declares it.
    Other(OtherAxis),
}

/// An axis of a kind of its own: its name, the quantity it is along, the unit, and the
/// value at each index.
#[derive(Debug, Clone, PartialEq)]
pub struct OtherAxis {
    /// Name of the array axis (`snake_case`, e.g. `band`).
    pub name: &'static str,
    /// The quantity along it, as an axis title says it (e.g. `"band centre"`).
    pub quantity: &'static str,
    /// Unit of the values (`""` when dimensionless).
    pub unit: &'static str,
    /// The value at each index.
    pub values: Vec<f64>,
}

impl Axis {
    /// Name of the array axis: `channel`, `bin`, `lag`, `modulation`, `feature`,
    /// `azimuth`, `alpha`, `delta`, or the other axis's own.
    pub fn name(&self) -> &'static str {
        match self {
            Axis::Channels(_) => "channel",
            Axis::Bins(_) => "bin",
            Axis::Lags(_) => "lag",
            Axis::Modulation(_) => "modulation",
            Axis::Features(_) => "feature",
            Axis::Azimuth(_) => "azimuth",
            Axis::Attenuation(_) => "alpha",
            Axis::Delay(_) => "delta",
            Axis::Other(o) => o.name,
        }
    }

    /// The quantity along the axis, as an axis title says it.
    pub fn quantity(&self) -> &'static str {
        match self {
            Axis::Channels(_) => "centre frequency",
            Axis::Bins(_) => "frequency",
            Axis::Lags(_) => "lag",
            Axis::Modulation(_) => "modulation frequency",
            Axis::Features(_) => "feature",
            Axis::Azimuth(_) => "azimuth",
            Axis::Attenuation(_) => "attenuation α",
            Axis::Delay(_) => "delay",
            Axis::Other(o) => o.quantity,
        }
    }

    /// Unit of the values along the axis (`""` for names and dimensionless values).
    pub fn unit(&self) -> &'static str {
        match self {
            Axis::Channels(_) | Axis::Bins(_) | Axis::Modulation(_) => "Hz",
            Axis::Lags(_) => "s",
            Axis::Azimuth(_) => "deg",
            Axis::Delay(_) => "samples",
            Axis::Features(_) | Axis::Attenuation(_) => "",
            Axis::Other(o) => o.unit,
        }
    }

    /// The value at each index; `None` for an axis of names.
    pub fn values(&self) -> Option<&[f64]> {
        match self {
            Axis::Channels(v)
            | Axis::Bins(v)
            | Axis::Lags(v)
            | Axis::Modulation(v)
            | Axis::Azimuth(v)
            | Axis::Attenuation(v)
            | Axis::Delay(v) => Some(v),
            Axis::Other(o) => Some(&o.values),
            Axis::Features(_) => None,
        }
    }

    /// The name at each index of an axis of names (features); `None` otherwise.
    pub fn labels(&self) -> Option<&[String]> {
        match self {
            Axis::Features(names) => Some(names),
            _ => None,
        }
    }

    /// Number of indices along the axis.
    pub fn len(&self) -> usize {
        self.values()
            .map_or_else(|| self.labels().map_or(0, <[String]>::len), <[f64]>::len)
    }

    /// Whether the axis has no index.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// `{"name", "quantity", "unit", "values"}`, or `"labels"` in place of `"values"` for an
/// axis of names.
impl Serialize for Axis {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(4))?;
        m.serialize_entry("name", self.name())?;
        m.serialize_entry("quantity", self.quantity())?;
        m.serialize_entry("unit", self.unit())?;
        match (self.values(), self.labels()) {
            (Some(v), _) => m.serialize_entry("values", v)?,
            (None, labels) => m.serialize_entry("labels", labels.unwrap_or_default())?,
        }
        m.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_axis_names_its_quantity_unit_and_values() {
        let lags = Axis::Lags(vec![-0.001, 0.0, 0.001]);
        assert_eq!(
            (lags.name(), lags.quantity(), lags.unit(), lags.len()),
            ("lag", "lag", "s", 3)
        );
        let f = Axis::Features(vec!["centroid".into()]);
        assert_eq!(
            (f.values(), f.labels().map(<[String]>::len)),
            (None, Some(1))
        );
        let v = serde_json::to_value(&f).expect("serialisable");
        assert_eq!(v["labels"][0], "centroid");
        assert!(v.get("values").is_none());
        let other = Axis::Other(OtherAxis {
            name: "band",
            quantity: "band centre",
            unit: "Bark",
            values: vec![1.0, 2.0],
        });
        let v = serde_json::to_value(&other).expect("serialisable");
        assert_eq!(
            (
                v["name"].as_str(),
                v["unit"].as_str(),
                v["values"][1].as_f64()
            ),
            (Some("band"), Some("Bark"), Some(2.0))
        );
        assert!(Axis::Azimuth(Vec::new()).is_empty());
    }
}
