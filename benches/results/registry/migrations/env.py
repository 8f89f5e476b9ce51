"""Alembic environment of the calibration registry: migrations run on the connection the registry hands in
(``config.attributes["connection"]``, see :func:`benches.results.registry.store.upgrade`), never on a URL of
their own. ``render_as_batch`` lets the same migration alter tables on SQLite (copy-and-move) and PostgreSQL.
"""

from alembic import context

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=None, render_as_batch=True)
with context.begin_transaction():
    context.run_migrations()
