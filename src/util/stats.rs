//! Order statistics of samples (nearest rank: the answer is one of the values).

/// The q-quantile (nearest rank, q in 0..=1) of the values; `None` when there are none.
pub fn quantile(mut v: Vec<f64>, q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    Some(v[((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize])
}

/// The median (nearest rank); `None` when there are no values.
pub fn median(v: Vec<f64>) -> Option<f64> {
    quantile(v, 0.5)
}

/// The arithmetic mean; 0 for no values.
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(quantile(vec![1.0, 2.0, 3.0, 4.0, 5.0], 0.9), Some(5.0));
        assert_eq!(median(vec![]), None);
        assert_eq!(mean(&[1.0, 2.0]), 1.5);
    }
}
