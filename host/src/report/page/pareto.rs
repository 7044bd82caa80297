//! The Pareto front of the settings (cost against error) and the setting the report
//! recommends.

/// One setting's cost and errors: lower cost, lower target error and higher Dice are better.
#[derive(Clone, Copy, Debug)]
pub(super) struct Point {
    pub cost: f64,
    pub tre_mm: f64,
    pub dice: f64,
}

/// Whether `a` dominates `b`: no worse on every axis and better on one.
fn dominates(a: &Point, b: &Point) -> bool {
    let no_worse = a.cost <= b.cost && a.tre_mm <= b.tre_mm && a.dice >= b.dice;
    let better = a.cost < b.cost || a.tre_mm < b.tre_mm || a.dice > b.dice;
    no_worse && better
}

/// The indices of the points no other point dominates, cheapest first. Points with a
/// non-finite value are never on the front.
pub(super) fn front(points: &[Point]) -> Vec<usize> {
    let finite = |p: &Point| p.cost.is_finite() && p.tre_mm.is_finite() && p.dice.is_finite();
    let mut on: Vec<usize> = (0..points.len())
        .filter(|&i| finite(&points[i]))
        .filter(|&i| !points.iter().any(|q| finite(q) && dominates(q, &points[i])))
        .collect();
    on.sort_by(|&a, &b| points[a].cost.total_cmp(&points[b].cost));
    on
}

/// How close to the best a setting must come to be recommended: target error within 5 % of
/// the best on the front (or 0.05 mm, whichever is larger: below that the tracking noise
/// decides). The target error is what the augmentation shows the surgeon; Dice, which only
/// says how well the outline fits, decides the front but not the choice on it.
pub(super) const RULE: &str = "the cheapest setting on the front whose target error is within \
     5 % (or 0.05 mm) of the best on the front: the target error is what the augmentation \
     shows, the outline (Dice) only helps decide the front";

/// The setting [`RULE`] picks among `front` (indices into `points`, cheapest first).
pub(super) fn recommend(points: &[Point], front: &[usize]) -> Option<usize> {
    let best = front
        .iter()
        .map(|&i| points[i].tre_mm)
        .fold(f64::INFINITY, f64::min);
    let tolerance = (0.05 * best).max(0.05);
    front
        .iter()
        .copied()
        .find(|&i| points[i].tre_mm <= best + tolerance)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(cost: f64, tre_mm: f64, dice: f64) -> Point {
        Point { cost, tre_mm, dice }
    }

    #[test]
    fn the_front_holds_exactly_the_undominated_points() {
        let points = [
            p(1.0, 5.0, 0.90), // cheapest: on the front
            p(2.0, 3.0, 0.95), // better error: on the front
            p(3.0, 3.5, 0.94), // dominated by the second
            p(4.0, 3.0, 0.96), // better Dice: on the front
            p(5.0, f64::NAN, 0.99),
        ];
        assert_eq!(front(&points), vec![0, 1, 3]);
    }

    #[test]
    fn the_recommendation_is_the_cheapest_near_the_best_target_error() {
        // The second is within 5 % of the best target error; the first is not.
        let points = [p(1.0, 5.0, 0.99), p(2.0, 3.1, 0.95), p(4.0, 3.0, 0.96)];
        let f = front(&points);
        assert_eq!(f, vec![0, 1, 2]);
        assert_eq!(recommend(&points, &f), Some(1));
        // 3.2 mm is not within 5 % of 3.0 mm.
        let points = [p(1.0, 5.0, 0.99), p(2.0, 3.2, 0.95), p(4.0, 3.0, 0.96)];
        let f = front(&points);
        assert_eq!(recommend(&points, &f), Some(2));
        // Below 1 mm the 0.05 mm floor counts.
        let points = [p(1.0, 0.54, 0.99), p(2.0, 0.5, 0.99)];
        let f = front(&points);
        assert_eq!(recommend(&points, &f), Some(0));
        assert_eq!(recommend(&[], &[]), None);
    }
}
