//! The subset of Python's pickle format that `torch.save` writes for a state dict: protocol 2-5
//! opcodes for tuples, dicts, strings, integers, floats and booleans, memo references, GLOBAL
//! names, REDUCE of the two callables a state dict uses (`collections.OrderedDict` and
//! `torch._utils._rebuild_tensor_v2`) and persistent ids (the storages). Nothing is executed:
//! an unknown callable or opcode is an error.

use std::collections::HashMap;

/// A storage reference from a persistent id: `('storage', torch.FloatStorage, key, location, numel)`.
#[derive(Clone, Debug, PartialEq)]
pub struct StorageRef {
    /// The storage class name, e.g. `FloatStorage`.
    pub class: String,
    /// The record name inside the archive (`<prefix>/data/<key>`).
    pub key: String,
    pub numel: u64,
}

/// A tensor view of a storage, as `_rebuild_tensor_v2` describes it.
#[derive(Clone, Debug, PartialEq)]
pub struct TensorRef {
    pub storage: StorageRef,
    pub offset: u64,
    pub shape: Vec<u64>,
    pub stride: Vec<u64>,
}

/// A pickled value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    None,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
    Bytes(Vec<u8>),
    Tuple(Vec<Value>),
    List(Vec<Value>),
    /// Dicts and OrderedDicts, in insertion order.
    Dict(Vec<(Value, Value)>),
    /// A `module name` reference from GLOBAL / STACK_GLOBAL.
    Global(String, String),
    Storage(StorageRef),
    Tensor(TensorRef),
}

impl Value {
    fn as_int(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            _ => None,
        }
    }
    fn as_str(&self) -> Option<&str> {
        match self {
            Value::Str(s) => Some(s),
            _ => None,
        }
    }
    fn ints(&self) -> Option<Vec<u64>> {
        match self {
            Value::Tuple(v) | Value::List(v) => v
                .iter()
                .map(|x| x.as_int().and_then(|i| u64::try_from(i).ok()))
                .collect(),
            _ => None,
        }
    }
}

/// Parse a pickle; the error says what was wrong and at which byte.
pub fn parse(data: &[u8]) -> Result<Value, String> {
    let mut m = Machine {
        data,
        pos: 0,
        stack: Vec::new(),
        marks: Vec::new(),
        memo: HashMap::new(),
        copied: 0,
    };
    m.run()
}

/// How many values the memo may copy in all, per byte of pickle (plus a floor): memo references
/// are copies here, and each copy of a container of copies doubles it, so a few hundred corrupt
/// bytes could otherwise ask for 2^100 values. A state dict's memo copies strings and small tuples.
const MEMO_COPIES_PER_BYTE: usize = 64;

/// Values in `v`, counted without recursion (the nesting may be deep).
fn size(v: &Value) -> usize {
    let mut n = 0;
    let mut todo = vec![v];
    while let Some(v) = todo.pop() {
        n += 1;
        match v {
            Value::Tuple(items) | Value::List(items) => todo.extend(items),
            Value::Dict(items) => todo.extend(items.iter().flat_map(|(k, v)| [k, v])),
            _ => {}
        }
    }
    n
}

struct Machine<'a> {
    data: &'a [u8],
    pos: usize,
    stack: Vec<Value>,
    marks: Vec<usize>,
    memo: HashMap<u32, Value>,
    /// Values copied into and out of the memo so far (see [`MEMO_COPIES_PER_BYTE`]).
    copied: usize,
}

impl Machine<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(format!("truncated at byte {} (needs {n} more)", self.pos));
        };
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16, String> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self) -> Result<u32, String> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn string(&mut self, n: usize) -> Result<String, String> {
        let at = self.pos;
        String::from_utf8(self.take(n)?.to_vec()).map_err(|_| format!("invalid UTF-8 at byte {at}"))
    }
    fn line(&mut self) -> Result<String, String> {
        let rest = &self.data[self.pos..];
        let n = rest
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| format!("unterminated line at byte {}", self.pos))?;
        let s = self.string(n)?;
        self.pos += 1;
        Ok(s)
    }
    fn pop(&mut self) -> Result<Value, String> {
        self.stack
            .pop()
            .ok_or_else(|| format!("stack underflow at byte {}", self.pos))
    }
    fn pop_mark(&mut self) -> Result<Vec<Value>, String> {
        let m = self
            .marks
            .pop()
            .ok_or_else(|| format!("no MARK before byte {}", self.pos))?;
        if m > self.stack.len() {
            return Err(format!("MARK past the stack at byte {}", self.pos));
        }
        Ok(self.stack.split_off(m))
    }
    fn top(&mut self) -> Result<&mut Value, String> {
        let pos = self.pos;
        self.stack
            .last_mut()
            .ok_or_else(|| format!("stack underflow at byte {pos}"))
    }
    /// Count a copy of `n` values against the budget, refusing one that would exceed it.
    fn copying(&mut self, n: usize) -> Result<(), String> {
        self.copied = self.copied.saturating_add(n);
        let budget = MEMO_COPIES_PER_BYTE * self.data.len() + 100_000;
        if self.copied > budget {
            return Err(format!(
                "memo references at byte {} copy more than {budget} values: corrupt (or not a state dict)",
                self.pos
            ));
        }
        Ok(())
    }
    fn memo_get(&mut self, k: u32) -> Result<Value, String> {
        let pos = self.pos;
        let n = size(
            self.memo
                .get(&k)
                .ok_or_else(|| format!("memo key {k} unset at byte {pos}"))?,
        );
        self.copying(n)?;
        Ok(self.memo[&k].clone())
    }
    fn memo_put(&mut self, k: u32) -> Result<(), String> {
        // A copy: state dicts never mutate a container after another reference to it is taken.
        let n = size(self.top()?);
        self.copying(n)?;
        let v = self.top()?.clone();
        self.memo.insert(k, v);
        Ok(())
    }

    fn run(&mut self) -> Result<Value, String> {
        loop {
            let at = self.pos;
            let op = self.u8()?;
            match op {
                0x80 => {
                    let v = self.u8()?;
                    if v > 5 {
                        return Err(format!("pickle protocol {v} is not supported"));
                    }
                }
                0x95 => {
                    self.take(8)?; // FRAME: a length hint only
                }
                b'.' => return self.pop(),
                b'(' => self.marks.push(self.stack.len()),
                b'N' => self.stack.push(Value::None),
                0x88 => self.stack.push(Value::Bool(true)),
                0x89 => self.stack.push(Value::Bool(false)),
                b'K' => {
                    let v = self.u8()?;
                    self.stack.push(Value::Int(v.into()))
                }
                b'M' => {
                    let v = self.u16()?;
                    self.stack.push(Value::Int(v.into()))
                }
                b'J' => {
                    let v = self.u32()? as i32;
                    self.stack.push(Value::Int(v.into()))
                }
                0x8a => {
                    // LONG1: little-endian two's complement of n bytes.
                    let n = self.u8()? as usize;
                    let b = self.take(n)?;
                    if n > 8 {
                        return Err(format!("integer of {n} bytes at byte {at}"));
                    }
                    let mut v: i64 = 0;
                    for (i, &x) in b.iter().enumerate() {
                        v |= (x as i64) << (8 * i);
                    }
                    if n > 0 && n < 8 && b[n - 1] & 0x80 != 0 {
                        v -= 1i64 << (8 * n);
                    }
                    self.stack.push(Value::Int(v))
                }
                b'G' => {
                    let b = self.take(8)?;
                    let v = f64::from_be_bytes(b.try_into().expect("8 bytes"));
                    self.stack.push(Value::Float(v))
                }
                b'X' => {
                    let n = self.u32()? as usize;
                    let s = self.string(n)?;
                    self.stack.push(Value::Str(s))
                }
                0x8c => {
                    let n = self.u8()? as usize;
                    let s = self.string(n)?;
                    self.stack.push(Value::Str(s))
                }
                b'C' => {
                    let n = self.u8()? as usize;
                    let b = self.take(n)?.to_vec();
                    self.stack.push(Value::Bytes(b))
                }
                b'B' => {
                    let n = self.u32()? as usize;
                    let b = self.take(n)?.to_vec();
                    self.stack.push(Value::Bytes(b))
                }
                b')' => self.stack.push(Value::Tuple(vec![])),
                b't' => {
                    let items = self.pop_mark()?;
                    self.stack.push(Value::Tuple(items))
                }
                0x85..=0x87 => {
                    let n = (op - 0x84) as usize;
                    if self.stack.len() < n {
                        return Err(format!("stack underflow at byte {at}"));
                    }
                    let items = self.stack.split_off(self.stack.len() - n);
                    self.stack.push(Value::Tuple(items))
                }
                b']' => self.stack.push(Value::List(vec![])),
                b'}' => self.stack.push(Value::Dict(vec![])),
                b'a' => {
                    let v = self.pop()?;
                    match self.top()? {
                        Value::List(l) => l.push(v),
                        _ => return Err(format!("APPEND to a non-list at byte {at}")),
                    }
                }
                b'e' => {
                    let items = self.pop_mark()?;
                    match self.top()? {
                        Value::List(l) => l.extend(items),
                        _ => return Err(format!("APPENDS to a non-list at byte {at}")),
                    }
                }
                b's' => {
                    let v = self.pop()?;
                    let k = self.pop()?;
                    match self.top()? {
                        Value::Dict(d) => d.push((k, v)),
                        _ => return Err(format!("SETITEM on a non-dict at byte {at}")),
                    }
                }
                b'u' => {
                    let items = self.pop_mark()?;
                    if items.len() % 2 != 0 {
                        return Err(format!("SETITEMS with an odd count at byte {at}"));
                    }
                    let mut it = items.into_iter();
                    let mut pairs = Vec::new();
                    while let (Some(k), Some(v)) = (it.next(), it.next()) {
                        pairs.push((k, v));
                    }
                    match self.top()? {
                        Value::Dict(d) => d.extend(pairs),
                        _ => return Err(format!("SETITEMS on a non-dict at byte {at}")),
                    }
                }
                b'q' => {
                    let k = self.u8()?;
                    self.memo_put(k.into())?
                }
                b'r' => {
                    let k = self.u32()?;
                    self.memo_put(k)?
                }
                0x94 => {
                    let k = self.memo.len() as u32;
                    self.memo_put(k)?
                }
                b'h' => {
                    let k = self.u8()?;
                    let v = self.memo_get(k.into())?;
                    self.stack.push(v)
                }
                b'j' => {
                    let k = self.u32()?;
                    let v = self.memo_get(k)?;
                    self.stack.push(v)
                }
                b'c' => {
                    let module = self.line()?;
                    let name = self.line()?;
                    self.stack.push(Value::Global(module, name))
                }
                0x93 => {
                    let name = self.pop()?;
                    let module = self.pop()?;
                    match (module, name) {
                        (Value::Str(m), Value::Str(n)) => self.stack.push(Value::Global(m, n)),
                        _ => return Err(format!("STACK_GLOBAL of non-strings at byte {at}")),
                    }
                }
                b'Q' => {
                    let pid = self.pop()?;
                    let storage = storage_ref(&pid)
                        .ok_or_else(|| format!("unsupported persistent id {pid:?} at byte {at}"))?;
                    self.stack.push(Value::Storage(storage))
                }
                b'R' => {
                    let args = self.pop()?;
                    let callable = self.pop()?;
                    let v = reduce(&callable, args).map_err(|e| format!("{e} at byte {at}"))?;
                    self.stack.push(v)
                }
                b'b' => {
                    // BUILD: OrderedDict state (`_metadata`) and tensor state are not needed.
                    self.pop()?;
                }
                _ => return Err(format!("unsupported pickle opcode 0x{op:02x} at byte {at}")),
            }
        }
    }
}

fn storage_ref(pid: &Value) -> Option<StorageRef> {
    let Value::Tuple(t) = pid else { return None };
    match t.as_slice() {
        [tag, Value::Global(_, class), key, _location, numel]
            if tag.as_str() == Some("storage") =>
        {
            Some(StorageRef {
                class: class.clone(),
                key: key.as_str()?.to_string(),
                numel: u64::try_from(numel.as_int()?).ok()?,
            })
        }
        _ => None,
    }
}

fn reduce(callable: &Value, args: Value) -> Result<Value, String> {
    let Value::Global(module, name) = callable else {
        return Err(format!("REDUCE of a non-callable {callable:?}"));
    };
    match (module.as_str(), name.as_str()) {
        ("collections", "OrderedDict") => Ok(Value::Dict(vec![])),
        ("torch._utils", "_rebuild_tensor_v2") => {
            let Value::Tuple(a) = args else {
                return Err("_rebuild_tensor_v2 without an argument tuple".into());
            };
            match a.as_slice() {
                [Value::Storage(s), offset, shape, stride, ..] => {
                    let bad = || "_rebuild_tensor_v2 with bad offset/size/stride".to_string();
                    let shape = shape.ints().ok_or_else(bad)?;
                    let stride = stride.ints().ok_or_else(bad)?;
                    let offset = offset
                        .as_int()
                        .and_then(|o| u64::try_from(o).ok())
                        .ok_or_else(bad)?;
                    if shape.len() != stride.len() {
                        return Err(bad());
                    }
                    Ok(Value::Tensor(TensorRef {
                        storage: s.clone(),
                        offset,
                        shape,
                        stride,
                    }))
                }
                _ => Err("_rebuild_tensor_v2 with unexpected arguments".into()),
            }
        }
        _ => Err(format!(
            "the pickle calls {module}.{name}, which a state dict does not need"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Memo references are copies: a pickle doubling one list 60 times is refused, not expanded
    /// to 2^60 values.
    #[test]
    fn memo_doubling_is_refused() {
        let mut p = b"\x80\x02]q\x00".to_vec();
        for _ in 0..60 {
            p.extend(b"h\x00h\x00\x86q\x00");
        }
        p.push(b'.');
        let e = parse(&p).unwrap_err();
        assert!(e.contains("copy more than"), "{e}");
        // A few copies are fine.
        let ok = b"\x80\x02]q\x00h\x00h\x00\x86.";
        assert!(matches!(parse(ok), Ok(Value::Tuple(t)) if t.len() == 2));
    }

    #[test]
    fn a_small_ordered_dict_with_a_tensor() {
        // Hand-assembled: OrderedDict({'w': _rebuild_tensor_v2(pid, 0, (2, 3), (3, 1), False, OrderedDict())})
        let mut p = vec![0x80, 2];
        p.extend(b"ccollections\nOrderedDict\nq\x00)R");
        p.extend(b"(X\x01\x00\x00\x00w");
        p.extend(b"ctorch._utils\n_rebuild_tensor_v2\n(");
        p.extend(b"(X\x07\x00\x00\x00storagectorch\nFloatStorage\nX\x01\x00\x00\x000X\x03\x00\x00\x00cpuK\x06tQ");
        p.extend(b"K\x00K\x02K\x03\x86K\x03K\x01\x86\x89h\x00)Rtq\x01R");
        p.extend(b"u}bh\x01.");
        // The last value is memo 1 (the argument tuple); check the dict by stopping before it.
        let dict_end = p.len() - 3;
        let mut q = p[..dict_end].to_vec();
        q.push(b'.');
        let Value::Dict(d) = parse(&q).unwrap() else {
            panic!("not a dict")
        };
        assert_eq!(d.len(), 1);
        let Value::Tensor(t) = &d[0].1 else {
            panic!("not a tensor")
        };
        assert_eq!(t.shape, vec![2, 3]);
        assert_eq!(t.stride, vec![3, 1]);
        assert_eq!(t.storage.key, "0");
        assert_eq!(t.storage.class, "FloatStorage");
        assert!(matches!(parse(&p).unwrap(), Value::Tuple(_)));
    }

    #[test]
    fn truncated_and_hostile_pickles_are_errors() {
        assert!(parse(b"\x80\x02X\x05\x00\x00\x00ab")
            .unwrap_err()
            .contains("truncated"));
        assert!(parse(b"\x80\x02cos\nsystem\nX\x02\x00\x00\x00ls\x85R.")
            .unwrap_err()
            .contains("os.system"));
        assert!(parse(b"\x80\x02h\x07.").unwrap_err().contains("memo"));
        assert!(parse(b"\x80\x02u.").unwrap_err().contains("MARK"));
    }
}
