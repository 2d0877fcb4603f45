//! MINC-2's container: HDF5, through the HDF5 C library (`hdf5-metno`). The image and its
//! scaling live under `/minc-2.0/image/0/`, the dimension variables under
//! `/minc-2.0/dimensions/`; a dataset names its dimensions in its `dimorder` attribute.

use std::path::Path;

use hdf5_metno as h5;
use hdf5_metno::types::{FixedAscii, TypeDescriptor, VarLenAscii, VarLenUnicode};

use super::{Attr, Container, Stored, Variable};
use crate::{IoError, Position};

pub(super) struct Hdf5<'a> {
    path: &'a Path,
    file: h5::File,
}

impl<'a> Hdf5<'a> {
    pub(super) fn open(path: &'a Path) -> Result<Hdf5<'a>, IoError> {
        // The library prints its own error stack on stderr unless told not to.
        h5::silence_errors(true);
        let file = h5::File::open(path).map_err(|e| {
            IoError::format(path, Position::File, format!("HDF5 could not open it: {e}"))
        })?;
        if !file.link_exists("minc-2.0") {
            return Err(IoError::format(
                path,
                Position::File,
                "an HDF5 file without a `minc-2.0` group: not a MINC-2 volume",
            ));
        }
        Ok(Hdf5 { path, file })
    }

    fn fail(&self, name: &str, e: impl std::fmt::Display) -> IoError {
        IoError::format(self.path, Position::Field(name.into()), e.to_string())
    }

    fn location(name: &str) -> String {
        match name {
            "image" | "image-min" | "image-max" => format!("minc-2.0/image/0/{name}"),
            dimension => format!("minc-2.0/dimensions/{dimension}"),
        }
    }

    fn text(attr: &h5::Attribute) -> Option<String> {
        match attr.dtype().ok()?.to_descriptor().ok()? {
            TypeDescriptor::FixedAscii(_) | TypeDescriptor::FixedUnicode(_) => attr
                .read_scalar::<FixedAscii<4096>>()
                .ok()
                .map(|s| s.as_str().to_string()),
            TypeDescriptor::VarLenAscii => attr
                .read_scalar::<VarLenAscii>()
                .ok()
                .map(|s| s.as_str().to_string()),
            TypeDescriptor::VarLenUnicode => attr
                .read_scalar::<VarLenUnicode>()
                .ok()
                .map(|s| s.as_str().to_string()),
            _ => None,
        }
    }
}

impl Container for Hdf5<'_> {
    fn variable(&self, name: &str) -> Result<Option<Variable>, IoError> {
        let location = Self::location(name);
        // Walk the path a group at a time: `link_exists` on a path whose middle is missing
        // is an error in HDF5 1.10.
        let mut at = String::new();
        for part in location.split('/') {
            if !at.is_empty() {
                at.push('/');
            }
            at.push_str(part);
            if !self.file.link_exists(&at) {
                return Ok(None);
            }
        }
        let data = self
            .file
            .dataset(&location)
            .map_err(|e| self.fail(name, e))?;
        let shape = data.shape();
        let mut attrs = Vec::new();
        for attr_name in data.attr_names().map_err(|e| self.fail(name, e))? {
            let Ok(attr) = data.attr(&attr_name) else {
                continue;
            };
            let value = match Self::text(&attr) {
                Some(text) => Attr::Text(text),
                None => match attr.read_raw::<f64>() {
                    Ok(numbers) => Attr::Numbers(numbers),
                    // Attributes isocube has no use for may be of any type.
                    Err(_) => continue,
                },
            };
            attrs.push((attr_name, value));
        }
        let order = attrs.iter().find_map(|(n, a)| match (n.as_str(), a) {
            ("dimorder", Attr::Text(t)) => Some(t.clone()),
            _ => None,
        });
        let dims = match order {
            // Only as many names as the dataset has dimensions (nibabel does the same with
            // a stale dimorder).
            Some(order) if order.split(',').count() >= shape.len() => order
                .split(',')
                .zip(&shape)
                .map(|(n, &len)| (n.trim().to_string(), len))
                .collect(),
            _ if shape.is_empty() => Vec::new(),
            _ => {
                return Err(self.fail(
                    name,
                    format!(
                        "a dataset of shape {shape:?} without a dimorder naming its dimensions"
                    ),
                ))
            }
        };
        let stored = match data
            .dtype()
            .and_then(|t| t.to_descriptor())
            .map_err(|e| self.fail(name, e))?
        {
            TypeDescriptor::Integer(size) => Stored::Int {
                bits: 8 * size as u32,
                signed: true,
            },
            TypeDescriptor::Unsigned(size) => Stored::Int {
                bits: 8 * size as u32,
                signed: false,
            },
            TypeDescriptor::Float(_) => Stored::Float,
            other => {
                return Err(self.fail(name, format!("values of type {other:?} are not read")));
            }
        };
        Ok(Some(Variable {
            dims,
            attrs,
            stored,
        }))
    }

    fn values(&self, name: &str, _: &Variable) -> Result<Vec<f64>, IoError> {
        let data = self
            .file
            .dataset(&Self::location(name))
            .map_err(|e| self.fail(name, e))?;
        data.read_raw::<f64>().map_err(|e| self.fail(name, e))
    }
}
