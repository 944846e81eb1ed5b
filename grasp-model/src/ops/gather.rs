//! Rows of a feature table gathered into a batch.
//!
//! `Tensor::index_select` zero-fills its output before copying into it and
//! has no notion of padding; batches of cached features are gathered every
//! training step, so this copies each row once, writes padding rows as
//! zeros, and returns a view without copying when the rows are a
//! consecutive range (evaluation walks the table in order).

use super::cpu::with_f32;
use candle_core::{Result, Tensor};

/// `(rows.len(), D)` from `table (N, D)`; `None` rows are zeros. The result
/// is a constant for autograd.
pub fn gather_rows(table: &Tensor, rows: &[Option<usize>]) -> Result<Tensor> {
    let (n, dim) = table.dims2()?;
    if let Some(bad) = rows.iter().flatten().find(|r| **r >= n) {
        candle_core::bail!("gather_rows: row {bad} is outside the table's {n} rows");
    }
    if let Some(start) = consecutive(rows) {
        return table.narrow(0, start, rows.len());
    }
    let data = with_f32("gather_rows", table, "table", |t| {
        let mut out = Vec::with_capacity(rows.len() * dim);
        for row in rows {
            match row {
                Some(r) => out.extend_from_slice(&t[r * dim..(r + 1) * dim]),
                None => out.resize(out.len() + dim, 0.0),
            }
        }
        out
    })?;
    Tensor::from_vec(data, (rows.len(), dim), table.device())
}

/// The first row when `rows` is `start, start + 1, ...` without padding.
fn consecutive(rows: &[Option<usize>]) -> Option<usize> {
    let start = (*rows.first()?)?;
    rows.iter()
        .enumerate()
        .all(|(i, r)| *r == Some(start + i))
        .then_some(start)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    fn table() -> Tensor {
        Tensor::arange(0f32, 12.0, &Device::Cpu)
            .unwrap()
            .reshape((4, 3))
            .unwrap()
    }

    #[test]
    fn gathers_rows_and_zero_padding() {
        let got: Vec<Vec<f32>> = gather_rows(&table(), &[Some(2), None, Some(0), Some(2)])
            .unwrap()
            .to_vec2()
            .unwrap();
        assert_eq!(
            got,
            vec![
                vec![6.0, 7.0, 8.0],
                vec![0.0; 3],
                vec![0.0, 1.0, 2.0],
                vec![6.0, 7.0, 8.0]
            ]
        );
    }

    #[test]
    fn consecutive_rows_are_a_view() {
        let t = table();
        let got = gather_rows(&t, &[Some(1), Some(2)]).unwrap();
        assert_eq!(
            got.to_vec2::<f32>().unwrap(),
            vec![vec![3.0, 4.0, 5.0], vec![6.0, 7.0, 8.0]]
        );
        assert_eq!(consecutive(&[Some(1), Some(2), None]), None);
        assert_eq!(consecutive(&[]), None);
        assert_eq!(gather_rows(&t, &[]).unwrap().dims(), &[0, 3]);
    }

    #[test]
    fn rows_outside_the_table_are_an_error() {
        let err = gather_rows(&table(), &[Some(4)]).unwrap_err().to_string();
        assert!(err.contains("row 4") && err.contains("4 rows"), "{err}");
    }
}
