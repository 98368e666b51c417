"""`python -m task_manager.protocol`: write schema/*.schema.json from the models."""

import json
from pathlib import Path

from task_manager.protocol.documents import DOCUMENTS

SCHEMA_FOLDER = Path(__file__).with_name('schema')
SCHEMA_ID_BASE = 'urn:task-manager:protocol:v1:'


def schema_documents() -> dict[str, str]:
    """key: file name, value: its text (a JSON Schema 2020-12 document per model)."""
    documents = {}
    for stem, model in DOCUMENTS.items():
        schema = {
            '$schema': 'https://json-schema.org/draft/2020-12/schema',
            '$id': f'{SCHEMA_ID_BASE}{stem}.schema.json',
            **model.model_json_schema(),
        }
        documents[f'{stem}.schema.json'] = json.dumps(schema, indent=2) + '\n'
    return documents


def main() -> None:
    for name, text in schema_documents().items():
        (SCHEMA_FOLDER / name).write_text(text)
        print(SCHEMA_FOLDER / name)


if __name__ == '__main__':
    main()
