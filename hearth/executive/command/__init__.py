"""The command layer: what a dialogue system or a tablet uses to start, watch and cancel
missions (docs/command-layer.md).

- :mod:`hearth.executive.command.vocabulary`: missions with their parameters and utterance
  templates (from the mission files), known objects, places and rooms (from the map),
  refreshed when the map changes.
- :mod:`hearth.executive.command.commands`: an utterance -> a mission and parameters, or a
  clarifying answer listing the candidates.
- :mod:`hearth.executive.command.service`: the executive, the vocabulary, approvals and the event
  hub behind one thread-safe object; :mod:`hearth.executive.command.api`: the FastAPI app over it.
"""
