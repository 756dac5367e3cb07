"""Everything read from records, in rooms from the ground up: tables, findings, then text | figures | collect, then
report | export. The layers contract in pyproject.toml names them."""
