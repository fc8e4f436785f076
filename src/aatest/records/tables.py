"""The records schema (SQLAlchemy Core), identical on SQLite and PostgreSQL.

Rows are only ever inserted, never updated or deleted (except the certificate counters): a
re-analysis or re-signing inserts a new ``calibrations`` row whose ``supersedes_id`` points at
the record it replaces. Every time is UTC.

- ``units``               one row per sensor unit (model, serial)
- ``certificate_counters`` the last number issued per (prefix, year), locked while allocating
- ``certificates``        every number ever issued (so the sequence is provably gap-free)
- ``calibrations``        one record per registered run/analysis/report/diagnosis, each hashed
                          onto a chain over all records (:mod:`aatest.records.chain`)
- ``signed_files``        SHA-256 of every file of the bundle, per record
- ``quantities``          the key results with their expanded uncertainty, per record
- ``reference_standards`` the lab's reference instruments with their calibration and due date
                          (retiring one sets ``retired_utc``; nothing else is ever updated)
- ``audit_log``           append-only: who changed what in the store, when and why, hash-chained
- ``certificate_status``  certificates superseded or withdrawn (one row each, never changed)
"""

from __future__ import annotations

from sqlalchemy import (
    JSON,
    Column,
    Date,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    MetaData,
    String,
    Table,
    Text,
    UniqueConstraint,
)

metadata = MetaData()

units = Table(
    "units", metadata,
    Column("id", Integer, primary_key=True),
    Column("model", String(64), nullable=False),
    Column("serial", String(64), nullable=False),
    UniqueConstraint("model", "serial", name="uq_units_model_serial"),
)

certificate_counters = Table(
    "certificate_counters", metadata,
    Column("prefix", String(16), primary_key=True),
    Column("year", Integer, primary_key=True),
    Column("last_number", Integer, nullable=False),
)

certificates = Table(
    "certificates", metadata,
    Column("number", String(40), primary_key=True),
    Column("prefix", String(16), nullable=False),
    Column("year", Integer, nullable=False),
    Column("sequence", Integer, nullable=False),
    Column("issued_utc", DateTime(timezone=True), nullable=False),
    UniqueConstraint("prefix", "year", "sequence", name="uq_certificates_sequence"),
)

calibrations = Table(
    "calibrations", metadata,
    Column("id", Integer, primary_key=True),
    Column("unit_id", Integer, ForeignKey("units.id"), nullable=False, index=True),
    Column("certificate_number", String(40), ForeignKey("certificates.number"), index=True),
    Column("supersedes_id", Integer, ForeignKey("calibrations.id")),
    Column("command", String(16), nullable=False),
    Column("procedure", String(128), nullable=False),
    Column("procedure_sha256", String(64)),
    Column("rig", JSON, nullable=False),
    Column("plugin_versions", JSON, nullable=False),
    Column("operator", String(128)),
    Column("lab", String(128), nullable=False),
    Column("calibrated_utc", DateTime(timezone=True), nullable=False),
    Column("registered_utc", DateTime(timezone=True), nullable=False),
    Column("overall_verdict", String(24), nullable=False),
    Column("verdicts", JSON, nullable=False),
    Column("results", JSON, nullable=False),
    Column("bundle", Text, nullable=False),
    Column("key_fingerprint", String(64)),
    Column("kind", String(16), nullable=False, server_default="calibration"),  # | simulation
    Column("previous_hash", String(64)),
    Column("row_hash", String(64)),
)

signed_files = Table(
    "signed_files", metadata,
    Column("calibration_id", Integer, ForeignKey("calibrations.id"), primary_key=True),
    Column("name", String(255), primary_key=True),
    Column("sha256", String(64), nullable=False),
)

quantities = Table(
    "quantities", metadata,
    Column("calibration_id", Integer, ForeignKey("calibrations.id"), primary_key=True),
    Column("name", String(64), primary_key=True),
    Column("value", Float, nullable=False),
    Column("expanded_uncertainty", Float),
    Column("unit", String(32), nullable=False),
)

reference_standards = Table(
    "reference_standards", metadata,
    Column("id", Integer, primary_key=True),
    Column("identifier", String(64), nullable=False, unique=True),
    Column("kind", String(32), nullable=False),
    Column("certificate_number", String(64), nullable=False),
    Column("issuing_lab", String(128), nullable=False),
    Column("calibrated_on", Date, nullable=False),
    Column("due_on", Date, nullable=False),
    Column("accuracy", Text, nullable=False),
    Column("added_utc", DateTime(timezone=True), nullable=False),
    Column("retired_utc", DateTime(timezone=True)),
    Column("retired_reason", Text),
)

audit_log = Table(
    "audit_log", metadata,
    Column("id", Integer, primary_key=True),
    Column("at_utc", DateTime(timezone=True), nullable=False),
    Column("who", String(128), nullable=False),
    Column("action", String(32), nullable=False),
    Column("subject", String(64), nullable=False),
    Column("reason", Text, nullable=False),
    Column("detail", JSON, nullable=False),
    Column("previous_hash", String(64), nullable=False),
    Column("row_hash", String(64), nullable=False),
)

certificate_status = Table(
    "certificate_status", metadata,
    Column("number", String(40), ForeignKey("certificates.number"), primary_key=True),
    Column("status", String(16), nullable=False),  # superseded | withdrawn
    Column("replaced_by", String(40), ForeignKey("certificates.number")),
    Column("reason", Text, nullable=False),
    Column("who", String(128), nullable=False),
    Column("at_utc", DateTime(timezone=True), nullable=False),
)
