"""A run's report: its data read from the store (``data``), drawn (``plots``) and written as Markdown (``markdown``)
and as one self-contained HTML page (``html``). Reports only read; ``python -m league.report`` plays what is missing
before it builds one."""
