"""The catalogue's alembic environment and revisions. The folder sits at the repository's top level and is
installed as the package ``twinreg.migrations`` (pyproject.toml maps it), so twinreg finds it through the
package, installed or editable, never by walking up folders."""
