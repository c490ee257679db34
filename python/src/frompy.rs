//! A serde `Deserializer` over Python objects: the inverse of [`crate::topy`], to read a
//! typed value back from what `topy` built (dicts for structs and maps, lists or tuples
//! for sequences, a variant's name or `{variant: value}` for enums). Floats pass
//! through as floats, non-finite ones included. Errors name the place in the argument
//! (`parts[1]["reach"]["instants"][3]`).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde::de::{self, DeserializeOwned, IntoDeserializer, Visitor};
use std::fmt::Display;

/// Read a `T` from `o`; `at` names it in messages.
pub fn from_py<T: DeserializeOwned>(o: &Bound<'_, PyAny>, at: &str) -> PyResult<T> {
    T::deserialize(FromPy {
        o: o.clone(),
        at: at.to_string(),
    })
    .map_err(|e| match e {
        Error::Py(e) => e,
        Error::Msg(m) => PyValueError::new_err(format!("{at}: not a samara result: {m}")),
    })
}

/// A failed read: a Python error, or serde's message (the place is in it).
#[derive(Debug)]
pub enum Error {
    Py(PyErr),
    Msg(String),
}

impl Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Error::Py(e) => write!(f, "{e}"),
            Error::Msg(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for Error {}

impl de::Error for Error {
    fn custom<M: Display>(m: M) -> Self {
        Error::Msg(m.to_string())
    }
}

impl From<PyErr> for Error {
    fn from(e: PyErr) -> Self {
        Error::Py(e)
    }
}

struct FromPy<'py> {
    o: Bound<'py, PyAny>,
    at: String,
}

impl<'py> FromPy<'py> {
    fn items(&self) -> Result<Option<Vec<Bound<'py, PyAny>>>, Error> {
        if let Ok(l) = self.o.downcast::<PyList>() {
            Ok(Some(l.iter().collect()))
        } else if let Ok(t) = self.o.downcast::<PyTuple>() {
            Ok(Some(t.iter().collect()))
        } else {
            Ok(None)
        }
    }

    fn bad(&self, what: &str) -> Error {
        let ty = self
            .o
            .get_type()
            .name()
            .map(|n| n.to_string())
            .unwrap_or_default();
        Error::Msg(format!("{}: {what}, not a {ty}", self.at))
    }
}

struct Seq<'py> {
    items: std::vec::IntoIter<Bound<'py, PyAny>>,
    at: String,
    i: usize,
}

impl<'de> de::SeqAccess<'de> for Seq<'_> {
    type Error = Error;
    fn next_element_seed<T: de::DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Error> {
        let Some(o) = self.items.next() else {
            return Ok(None);
        };
        let at = format!("{}[{}]", self.at, self.i);
        self.i += 1;
        seed.deserialize(FromPy { o, at }).map(Some)
    }
}

struct Map<'py> {
    items: std::vec::IntoIter<(Bound<'py, PyAny>, Bound<'py, PyAny>)>,
    value: Option<(Bound<'py, PyAny>, String)>,
    at: String,
}

impl<'de> de::MapAccess<'de> for Map<'_> {
    type Error = Error;
    fn next_key_seed<K: de::DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Error> {
        let Some((k, v)) = self.items.next() else {
            return Ok(None);
        };
        let at = format!("{}[{}]", self.at, k.repr().map(|r| r.to_string())?);
        self.value = Some((v, at.clone()));
        seed.deserialize(FromPy { o: k, at }).map(Some)
    }
    fn next_value_seed<V: de::DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, Error> {
        let (o, at) = self
            .value
            .take()
            .ok_or_else(|| Error::Msg("a value without its key".into()))?;
        seed.deserialize(FromPy { o, at })
    }
}

/// An enum given as `{variant: value}`.
struct Enum<'py> {
    variant: String,
    value: FromPy<'py>,
}

impl<'de> de::EnumAccess<'de> for Enum<'_> {
    type Error = Error;
    type Variant = Self;
    fn variant_seed<V: de::DeserializeSeed<'de>>(self, seed: V) -> Result<(V::Value, Self), Error> {
        let d: de::value::StringDeserializer<Error> = self.variant.clone().into_deserializer();
        Ok((seed.deserialize(d)?, self))
    }
}

impl<'de> de::VariantAccess<'de> for Enum<'_> {
    type Error = Error;
    fn unit_variant(self) -> Result<(), Error> {
        Ok(())
    }
    fn newtype_variant_seed<T: de::DeserializeSeed<'de>>(self, seed: T) -> Result<T::Value, Error> {
        seed.deserialize(self.value)
    }
    fn tuple_variant<V: Visitor<'de>>(self, _: usize, v: V) -> Result<V::Value, Error> {
        de::Deserializer::deserialize_seq(self.value, v)
    }
    fn struct_variant<V: Visitor<'de>>(
        self,
        _: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Error> {
        de::Deserializer::deserialize_map(self.value, v)
    }
}

impl<'de> de::Deserializer<'de> for FromPy<'_> {
    type Error = Error;

    fn deserialize_any<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        let o = &self.o;
        if o.is_none() {
            v.visit_unit()
        } else if let Ok(b) = o.downcast::<PyBool>() {
            v.visit_bool(b.is_true())
        } else if let Ok(i) = o.downcast::<PyInt>() {
            match i.extract::<u64>() {
                Ok(u) => v.visit_u64(u),
                Err(_) => v.visit_i64(i.extract::<i64>()?),
            }
        } else if let Ok(x) = o.downcast::<PyFloat>() {
            v.visit_f64(x.value())
        } else if let Ok(s) = o.downcast::<PyString>() {
            v.visit_string(s.to_cow()?.into_owned())
        } else if o.downcast::<PyDict>().is_ok() {
            self.deserialize_map(v)
        } else if let Some(items) = self.items()? {
            v.visit_seq(Seq {
                items: items.into_iter(),
                at: self.at,
                i: 0,
            })
        } else if o.hasattr("tolist")? {
            // A numpy array or scalar: its plain Python value.
            let plain = o.call_method0("tolist")?;
            FromPy {
                o: plain,
                at: self.at,
            }
            .deserialize_any(v)
        } else {
            Err(self.bad("a number, string, list or dict"))
        }
    }

    fn deserialize_f64<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        if let Ok(x) = self.o.extract::<f64>() {
            if self.o.downcast::<PyBool>().is_err() {
                return v.visit_f64(x);
            }
        }
        Err(self.bad("a number"))
    }

    fn deserialize_f32<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        self.deserialize_f64(v)
    }

    fn deserialize_option<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        if self.o.is_none() {
            v.visit_none()
        } else {
            v.visit_some(self)
        }
    }

    fn deserialize_seq<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        let items = match self.items()? {
            Some(items) => items,
            None if self.o.hasattr("tolist")? => {
                let plain = self.o.call_method0("tolist")?;
                return FromPy {
                    o: plain,
                    at: self.at,
                }
                .deserialize_seq(v);
            }
            None => return Err(self.bad("a list")),
        };
        v.visit_seq(Seq {
            items: items.into_iter(),
            at: self.at,
            i: 0,
        })
    }

    fn deserialize_tuple<V: Visitor<'de>>(self, _: usize, v: V) -> Result<V::Value, Error> {
        self.deserialize_seq(v)
    }

    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: usize,
        v: V,
    ) -> Result<V::Value, Error> {
        self.deserialize_seq(v)
    }

    fn deserialize_map<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        let Ok(d) = self.o.downcast::<PyDict>() else {
            return Err(self.bad("a dict"));
        };
        let items: Vec<_> = d.iter().collect();
        v.visit_map(Map {
            items: items.into_iter(),
            value: None,
            at: self.at,
        })
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Error> {
        self.deserialize_map(v)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Error> {
        if let Ok(s) = self.o.downcast::<PyString>() {
            let name: String = s.to_cow()?.into_owned();
            let d: de::value::StringDeserializer<Error> = name.into_deserializer();
            return v.visit_enum(d);
        }
        let Ok(d) = self.o.downcast::<PyDict>() else {
            return Err(self.bad("a variant name or {variant: value}"));
        };
        if d.len() != 1 {
            return Err(self.bad("one {variant: value} pair"));
        }
        let (k, value) = d.iter().next().expect("one item");
        let variant: String = k.extract()?;
        let at = format!("{}[{variant:?}]", self.at);
        v.visit_enum(Enum {
            variant,
            value: FromPy { o: value, at },
        })
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        v: V,
    ) -> Result<V::Value, Error> {
        v.visit_newtype_struct(self)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string
        bytes byte_buf unit unit_struct identifier ignored_any
    }
}
