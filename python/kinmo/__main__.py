from kinmo.cli import app

app()
