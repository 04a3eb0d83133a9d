-- sandswim schema, migration 19: who pays for an attempt is decided once, when its lease is
-- granted (issue 31; server/store/rounds.h DecideLeasePayer).
--
-- leases.payer_campaign_run_id: the adaptive campaign run whose ledger charges this attempt in
-- full: the earliest one, not stopped and none of its sweeps cancelled, that held the run (a bed:
-- one of its runs) at the grant, by the ledger's own definition of its runs (rounds.cc
-- HeldRunsSql). NULL: no adaptive campaign run held it then, or granted before this migration.
-- leases.payer_decided: 1 once the grant decided the payer (every lease granted from this
-- migration on); 0 for leases granted before it, which the ledger charges by its earlier rule.
ALTER TABLE leases ADD COLUMN payer_campaign_run_id INTEGER;
ALTER TABLE leases ADD COLUMN payer_decided INTEGER NOT NULL DEFAULT 0;
