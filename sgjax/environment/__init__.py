"""Layer 3, the environment: ``physics`` (the sub-step loop), ``env`` (``SocialNavEnv``: reset
and step for one episode), ``options`` (the typed options of ``make``) and ``registry``
(``make``, ``registered``). The public names are exported by ``sgjax`` itself."""
