"""Layer 2, terms: the one term contract (``contract``: ``TermInput``, ``Term``), the registry,
the spec parser and term sets every kind shares (``base``), the state queries terms share
(``queries``) and episode enders (``enders``). The observation and reward terms are the
packages ``sgjax.observations`` and ``sgjax.rewards``; the named term sets that pick among
them are ``sgjax.environment.presets``."""
