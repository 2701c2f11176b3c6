//! The store's schema: versioned migrations kept in the repository (`migrations/NNNN_*.sql`,
//! compiled in) and applied once each, in order, recorded in `fleet_schema_migrations`; and the
//! daily partitions of the time-partitioned tables.

use std::collections::HashSet;

use postgres::{Client, GenericClient};

/// The migrations, in order: (version, name, SQL).
pub const MIGRATIONS: &[(i32, &str, &str)] = &[
    (1, "fleet", include_str!("../migrations/0001_fleet.sql")),
    (2, "models", include_str!("../migrations/0002_models.sql")),
    (3, "shadow", include_str!("../migrations/0003_shadow.sql")),
    (4, "probes", include_str!("../migrations/0004_probes.sql")),
];

/// Applies the migrations not applied yet, each in a transaction of its own; returns the
/// versions applied now. Two ingesters starting at once: the table lock makes the second wait
/// and then find the work done.
pub fn migrate(db: &mut Client) -> Result<Vec<i32>, postgres::Error> {
    db.batch_execute(
        "CREATE TABLE IF NOT EXISTS fleet_schema_migrations (
             version integer PRIMARY KEY, name text NOT NULL,
             applied_at timestamptz NOT NULL DEFAULT now())",
    )?;
    let mut applied = Vec::new();
    for (version, name, sql) in MIGRATIONS {
        let mut tx = db.transaction()?;
        tx.batch_execute("LOCK TABLE fleet_schema_migrations IN EXCLUSIVE MODE")?;
        let done = tx
            .query_opt(
                "SELECT 1 FROM fleet_schema_migrations WHERE version = $1",
                &[version],
            )?
            .is_some();
        if !done {
            tx.batch_execute(sql)?;
            tx.execute(
                "INSERT INTO fleet_schema_migrations (version, name) VALUES ($1, $2)",
                &[version, name],
            )?;
            applied.push(*version);
        }
        tx.commit()?;
    }
    Ok(applied)
}

/// The civil date (UTC) of a day since the Unix epoch (Howard Hinnant's algorithm).
pub fn civil_date(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// The daily partitions that exist (this process created or found them).
#[derive(Default)]
pub struct Partitions {
    known: HashSet<(&'static str, i64)>,
}

impl Partitions {
    /// Makes sure `table` has the partition of the UTC day holding `t_ms`.
    pub fn ensure(
        &mut self,
        db: &mut impl GenericClient,
        table: &'static str,
        t_ms: i64,
    ) -> Result<(), postgres::Error> {
        let day = t_ms.div_euclid(86_400_000);
        if self.known.contains(&(table, day)) {
            return Ok(());
        }
        let (y, m, d) = civil_date(day);
        let (y2, m2, d2) = civil_date(day + 1);
        db.batch_execute(&format!(
            "CREATE TABLE IF NOT EXISTS {table}_p{y:04}{m:02}{d:02} PARTITION OF {table} \
             FOR VALUES FROM ('{y:04}-{m:02}-{d:02} 00:00:00+00') TO ('{y2:04}-{m2:02}-{d2:02} 00:00:00+00')"
        ))?;
        self.known.insert((table, day));
        Ok(())
    }

    /// Forgets what exists (after a reconnect: another process may have dropped partitions).
    pub fn forget(&mut self) {
        self.known.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::civil_date;

    #[test]
    fn days_become_dates() {
        assert_eq!(civil_date(0), (1970, 1, 1));
        assert_eq!(civil_date(59), (1970, 3, 1));
        assert_eq!(civil_date(11_016), (2000, 2, 29));
        assert_eq!(civil_date(20_786), (2026, 11, 29));
        assert_eq!(civil_date(-1), (1969, 12, 31));
    }
}
