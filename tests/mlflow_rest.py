"""Asking an MLflow tracking server through its REST API, as any client of a lab's server would."""

import json
import urllib.request


def rest(server: str, method: str, path: str, body: dict | None = None) -> dict:
    """One request to ``<server>/api/2.0/mlflow/<path>`` (a JSON body for POST); the JSON answer."""
    request = urllib.request.Request(
        f"{server}/api/2.0/mlflow/{path}",
        method=method,
        data=None if body is None else json.dumps(body).encode(),
        headers={"Content-Type": "application/json"},
    )
    with urllib.request.urlopen(request, timeout=60) as answer:
        return json.loads(answer.read())
