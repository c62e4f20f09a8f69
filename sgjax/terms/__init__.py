"""Layer 2, terms: the one term contract (``contract``: ``TermInput``, ``Term``), the registry,
the spec parser and term sets every kind shares (``base``), the state queries terms share
(``queries``), episode enders (``enders``) and named term sets (``presets``). The observation
and reward terms are the packages ``sgjax.observations`` and ``sgjax.rewards``."""
