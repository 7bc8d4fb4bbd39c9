//! PyTorch checkpoints (`torch.save` since 1.6): a zip archive holding `<name>/data.pkl` (the
//! pickled state dict, see [`super::pickle`]) and one raw little-endian record per storage under
//! `<name>/data/<key>`. Only float32 tensors are loaded (the BatchNorm `num_batches_tracked`
//! counters are int64 and unused).

use super::pickle::{self, TensorRef, Value};
use crate::error::{Error, Result};
use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::{Path, PathBuf};

/// A dense row-major float tensor.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

impl Tensor {
    pub fn new(shape: Vec<usize>, data: Vec<f32>) -> Self {
        assert_eq!(
            shape.iter().product::<usize>(),
            data.len(),
            "tensor shape {shape:?} does not match its {} values",
            data.len()
        );
        Tensor { shape, data }
    }
    pub fn len(&self) -> usize {
        self.data.len()
    }
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// The same values under another shape with as many elements.
    pub fn reshape(&self, shape: &[usize]) -> Tensor {
        Tensor::new(shape.to_vec(), self.data.clone())
    }
    /// The transpose of a matrix (a Linear weight `out x in` becomes MatMul's `in x out`).
    pub fn t(&self) -> Tensor {
        let [r, c] = self.shape[..] else {
            panic!("transpose of a {:?} tensor", self.shape)
        };
        let mut out = vec![0f32; r * c];
        for i in 0..r {
            for j in 0..c {
                out[j * r + i] = self.data[i * c + j];
            }
        }
        Tensor::new(vec![c, r], out)
    }
}

/// The float tensors of a checkpoint by name.
pub struct StateDict {
    pub path: PathBuf,
    pub tensors: BTreeMap<String, Tensor>,
}

impl StateDict {
    /// Read a checkpoint. Every problem is an error naming the file: not a zip archive (e.g.
    /// truncated), no `data.pkl`, a pickle that is not a state dict, a storage record that is
    /// missing or shorter than its tensors need.
    pub fn load(path: &Path) -> Result<Self> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        Self::parse(path, std::io::BufReader::new(file))
    }

    /// [`StateDict::load`] on a stream of the file's bytes (`path` names it in errors).
    pub fn parse<R: std::io::Read + std::io::Seek>(path: &Path, r: R) -> Result<Self> {
        let bad = |msg: String| Error::format(path, msg);
        let mut zip = zip::ZipArchive::new(r).map_err(|e| {
            bad(format!(
                "not a PyTorch checkpoint (its zip archive cannot be read: {e}); a truncated download looks like this"
            ))
        })?;
        let pkl_name = zip
            .file_names()
            .find(|n| n.ends_with("data.pkl") && n.matches('/').count() <= 1)
            .map(str::to_string)
            .ok_or_else(|| bad("no data.pkl in the archive: not a PyTorch checkpoint".into()))?;
        let prefix = pkl_name.trim_end_matches("data.pkl").to_string();
        let pkl = read_entry(&mut zip, &pkl_name).map_err(&bad)?;
        let root = pickle::parse(&pkl).map_err(|e| bad(format!("{pkl_name}: {e}")))?;
        let Value::Dict(items) = root else {
            return Err(bad(format!("{pkl_name} holds no state dict")));
        };
        let mut storages: HashMap<String, Vec<u8>> = HashMap::new();
        let mut tensors = BTreeMap::new();
        for (k, v) in items {
            let (Value::Str(name), Value::Tensor(t)) = (k, v) else {
                continue;
            };
            if t.storage.class != "FloatStorage" {
                continue;
            }
            if !storages.contains_key(&t.storage.key) {
                let rec = format!("{prefix}data/{}", t.storage.key);
                let bytes = read_entry(&mut zip, &rec).map_err(&bad)?;
                storages.insert(t.storage.key.clone(), bytes);
            }
            let tensor = gather(&t, &storages[&t.storage.key])
                .map_err(|e| bad(format!("tensor {name}: {e}")))?;
            tensors.insert(name, tensor);
        }
        Ok(StateDict {
            path: path.to_path_buf(),
            tensors,
        })
    }

    /// A tensor by name, checked to have the expected shape.
    pub fn get(&self, name: &str, shape: &[usize]) -> Result<&Tensor> {
        let t = self.tensors.get(name).ok_or_else(|| {
            Error::format(
                &self.path,
                format!("the checkpoint has no tensor {name}: not a MobileSAM checkpoint"),
            )
        })?;
        if t.shape != shape {
            return Err(Error::format(
                &self.path,
                format!(
                    "tensor {name} has shape {:?}, MobileSAM's is {shape:?}",
                    t.shape
                ),
            ));
        }
        Ok(t)
    }
}

fn read_entry<R: std::io::Read + std::io::Seek>(
    zip: &mut zip::ZipArchive<R>,
    name: &str,
) -> std::result::Result<Vec<u8>, String> {
    let mut f = zip
        .by_name(name)
        .map_err(|e| format!("record {name}: {e}"))?;
    // The size is the archive's word for it: reserve no more than a sane record, the read grows.
    let mut out = Vec::with_capacity(f.size().min(1 << 26) as usize);
    // Reading to the end also checks the record's CRC-32.
    f.read_to_end(&mut out)
        .map_err(|e| format!("record {name} cannot be read: {e}"))?;
    Ok(out)
}

/// The tensor's values in row-major order from its (possibly strided, offset) storage.
fn gather(t: &TensorRef, bytes: &[u8]) -> std::result::Result<Tensor, String> {
    let avail = bytes.len() / 4;
    if (avail as u64) < t.storage.numel {
        return Err(format!(
            "its storage record has {avail} floats, the pickle says {}",
            t.storage.numel
        ));
    }
    let shape: Vec<usize> = t.shape.iter().map(|&d| d as usize).collect();
    // Checked: a corrupt shape or stride must not wrap past the storage check.
    let n = t.shape.iter().try_fold(1u64, |a, &d| a.checked_mul(d));
    // The furthest element the view touches must lie inside the storage.
    let last = t
        .shape
        .iter()
        .zip(&t.stride)
        .try_fold(t.offset, |a, (&d, &s)| {
            d.saturating_sub(1)
                .checked_mul(s)
                .and_then(|x| a.checked_add(x))
        });
    let (Some(n), Some(last)) = (n, last) else {
        return Err(format!(
            "view (offset {}, shape {:?}, stride {:?}) overflows",
            t.offset, t.shape, t.stride
        ));
    };
    // A state dict's tensors do not repeat stored values (no zero strides): more elements than
    // the storage holds is a corrupt shape, and would size the allocation below.
    if n > t.storage.numel {
        return Err(format!(
            "view of shape {:?} has {n} elements, more than its {} stored floats",
            t.shape, t.storage.numel
        ));
    }
    let n = n as usize;
    if n > 0 && last >= t.storage.numel {
        return Err(format!(
            "view (offset {}, shape {:?}, stride {:?}) reaches past its {} stored floats",
            t.offset, t.shape, t.stride, t.storage.numel
        ));
    }
    let at = |i: usize| f32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().expect("4 bytes"));
    let mut data = Vec::with_capacity(n);
    let mut idx = vec![0usize; shape.len()];
    for _ in 0..n {
        let off = t.offset as usize
            + idx
                .iter()
                .zip(&t.stride)
                .map(|(&i, &s)| i * s as usize)
                .sum::<usize>();
        data.push(at(off));
        for d in (0..shape.len()).rev() {
            idx[d] += 1;
            if idx[d] < shape[d] {
                break;
            }
            idx[d] = 0;
        }
    }
    Ok(Tensor::new(shape, data))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sam::convert::pickle::StorageRef;

    #[test]
    fn strided_and_offset_views_are_gathered() {
        let bytes: Vec<u8> = (0..12).flat_map(|i| (i as f32).to_le_bytes()).collect();
        let view = |offset, shape: Vec<u64>, stride: Vec<u64>| TensorRef {
            storage: StorageRef {
                class: "FloatStorage".into(),
                key: "0".into(),
                numel: 12,
            },
            offset,
            shape,
            stride,
        };
        // A transposed 3x4 matrix.
        let t = gather(&view(0, vec![4, 3], vec![1, 4]), &bytes).unwrap();
        assert_eq!(t.data[..4], [0.0, 4.0, 8.0, 1.0]);
        // An offset row.
        let t = gather(&view(8, vec![4], vec![1]), &bytes).unwrap();
        assert_eq!(t.data, [8.0, 9.0, 10.0, 11.0]);
        // A view past the end of the storage.
        assert!(gather(&view(9, vec![4], vec![1]), &bytes)
            .unwrap_err()
            .contains("past"));
        // A storage record shorter than the pickle says.
        assert!(gather(&view(0, vec![2], vec![1]), &bytes[..20])
            .unwrap_err()
            .contains("storage record"));
        // Shapes and strides that overflow, or repeat values, are errors, not wrapped offsets
        // or huge allocations.
        for (shape, stride, why) in [
            (vec![1 << 40, 1 << 40], vec![0, 0], "overflows"),
            (vec![3, 2], vec![1 << 63, 1], "overflows"),
            (vec![100_000, 100_000], vec![0, 0], "more than"),
        ] {
            let e = gather(&view(0, shape, stride), &bytes).unwrap_err();
            assert!(e.contains(why), "{e}");
        }
    }
}
