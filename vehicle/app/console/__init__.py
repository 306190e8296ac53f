"""The trainer console: datasets, a training wizard, live training runs, a model manager and a
leaderboard in the browser (``vehicle console``, ``manage.py console``; see docs/console.md).

Modules: ``server`` (aiohttp application, auth, event stream), ``api`` (JSON routes),
``datasets`` (the car's tubs and their statistics), ``jobs`` (the queue of worker processes),
``worker`` (the process that trains or evaluates), ``static/`` (the page and its vendored chart
library). Nothing heavy is imported here.
"""
