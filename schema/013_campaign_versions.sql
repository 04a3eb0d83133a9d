-- sandswim schema, migration 13: campaigns of one's own, versioned (issue 29;
-- server/store/campaigns.h). Every change of a stored campaign is a new version; a campaign run
-- records the definition it ran, so that its claims, report and drift read what ran, not what the
-- campaign says today.

-- Every version of every stored campaign, kept when the campaign is deleted (its runs still name
-- it). A campaign deleted and stored again goes on from its last version.
CREATE TABLE campaign_versions (
  name            TEXT NOT NULL,
  version         INTEGER NOT NULL CHECK (version >= 1),
  definition      TEXT NOT NULL,                -- JSON as written (may hold "extends")
  resolved        TEXT NOT NULL,                -- JSON as ParseCampaign() reads it: no "extends"
  extends         TEXT,                         -- the base's name, NULL: none
  extends_version INTEGER,                      -- the base's version it was resolved against (0: built-in)
  created_at      REAL NOT NULL,
  PRIMARY KEY (name, version)
);
-- Campaigns stored before this migration: version 1, as written = resolved.
INSERT INTO campaign_versions (name, version, definition, resolved, created_at)
  SELECT name, 1, definition, definition, updated_at FROM campaigns;

-- campaigns.definition is the current version's resolved definition (FindCampaign reads it).
ALTER TABLE campaigns ADD COLUMN version INTEGER NOT NULL DEFAULT 1;

-- What a campaign run ran: the campaign's version (0: a built-in campaign), its resolved
-- definition and the SHA-256 of that definition's canonical dump (keys sorted, no spaces). NULL
-- for campaign runs made before this migration (the definition they ran was not kept).
ALTER TABLE campaign_runs ADD COLUMN campaign_version INTEGER;
ALTER TABLE campaign_runs ADD COLUMN definition TEXT;
ALTER TABLE campaign_runs ADD COLUMN definition_sha256 TEXT;

-- Who registered a schedule: 'flag' (sandswimd --schedule; a start without the flag disables it)
-- or 'api' (PUT /api/v1/campaigns/{name}/schedule; stored until deleted, whatever the flags).
ALTER TABLE campaign_schedules ADD COLUMN source TEXT NOT NULL DEFAULT 'flag' CHECK (source IN ('flag', 'api'));
