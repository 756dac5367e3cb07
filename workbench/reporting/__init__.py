"""Everything read from records, in rooms from the ground up: tables, findings, then text | figures | collect, then
export, then report (whose "Pose the rigs" panel draws the export's rigs). The layers contract in pyproject.toml
names them."""
