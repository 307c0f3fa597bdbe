//! PostgreSQL connections that prepare each statement once. `postgres`'s calls by SQL text
//! prepare the statement every time — a round trip, a parse and a plan — before running it;
//! under load that was most of the database's CPU (measured with perf during the load tests:
//! the parser and planner led PostgreSQL's profile). Here each connection keeps the statements
//! it has prepared, by their text, and later calls only bind and run.

use std::collections::HashMap;

use postgres::types::ToSql;
use postgres::{Client, GenericClient, IsolationLevel, Row, Statement, Transaction};

/// Statements a connection keeps at most; the store's SQL is a fixed set far below this, so
/// reaching it means text was built from values, and the cache starts again.
const MOST_STATEMENTS: usize = 256;

type Params<'a> = &'a [&'a (dyn ToSql + Sync)];

/// A connection and the statements prepared on it.
pub(super) struct Conn {
    client: Client,
    prepared: HashMap<String, Statement>,
}

/// A transaction on a `Conn`, using its statements.
pub(super) struct Tx<'a> {
    tx: Transaction<'a>,
    prepared: &'a mut HashMap<String, Statement>,
}

fn statement(
    prepared: &mut HashMap<String, Statement>,
    c: &mut impl GenericClient,
    sql: &str,
) -> Result<Statement, postgres::Error> {
    if let Some(s) = prepared.get(sql) {
        return Ok(s.clone());
    }
    if prepared.len() >= MOST_STATEMENTS {
        prepared.clear();
    }
    let s = c.prepare(sql)?;
    prepared.insert(sql.to_string(), s.clone());
    Ok(s)
}

/// What the store runs, by SQL text, on a connection or in a transaction.
pub(super) trait Sql {
    fn query(&mut self, sql: &str, params: Params<'_>) -> Result<Vec<Row>, postgres::Error>;
    fn query_opt(&mut self, sql: &str, params: Params<'_>) -> Result<Option<Row>, postgres::Error>;
    fn query_one(&mut self, sql: &str, params: Params<'_>) -> Result<Row, postgres::Error>;
    fn execute(&mut self, sql: &str, params: Params<'_>) -> Result<u64, postgres::Error>;
}

macro_rules! impl_sql {
    ($t:ty, $client:ident) => {
        impl Sql for $t {
            fn query(&mut self, sql: &str, params: Params<'_>) -> Result<Vec<Row>, postgres::Error> {
                let s = statement(&mut self.prepared, &mut self.$client, sql)?;
                self.$client.query(&s, params)
            }
            fn query_opt(&mut self, sql: &str, params: Params<'_>) -> Result<Option<Row>, postgres::Error> {
                let s = statement(&mut self.prepared, &mut self.$client, sql)?;
                self.$client.query_opt(&s, params)
            }
            fn query_one(&mut self, sql: &str, params: Params<'_>) -> Result<Row, postgres::Error> {
                let s = statement(&mut self.prepared, &mut self.$client, sql)?;
                self.$client.query_one(&s, params)
            }
            fn execute(&mut self, sql: &str, params: Params<'_>) -> Result<u64, postgres::Error> {
                let s = statement(&mut self.prepared, &mut self.$client, sql)?;
                self.$client.execute(&s, params)
            }
        }
    };
}

impl_sql!(Conn, client);
impl_sql!(Tx<'_>, tx);

impl Conn {
    pub fn new(client: Client) -> Self {
        Self { client, prepared: HashMap::new() }
    }

    pub fn batch_execute(&mut self, sql: &str) -> Result<(), postgres::Error> {
        self.client.batch_execute(sql)
    }

    pub fn transaction(&mut self) -> Result<Tx<'_>, postgres::Error> {
        Ok(Tx { tx: self.client.transaction()?, prepared: &mut self.prepared })
    }

    /// A read-only transaction whose reads all see one snapshot.
    pub fn snapshot(&mut self) -> Result<Tx<'_>, postgres::Error> {
        let tx = self.client.build_transaction().read_only(true).isolation_level(IsolationLevel::RepeatableRead);
        Ok(Tx { tx: tx.start()?, prepared: &mut self.prepared })
    }
}

impl Tx<'_> {
    pub fn commit(self) -> Result<(), postgres::Error> {
        self.tx.commit()
    }

    pub fn rollback(self) -> Result<(), postgres::Error> {
        self.tx.rollback()
    }
}
